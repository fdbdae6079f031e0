"""A motion sampled at other times (modb_kernel.resample: rotations slerped joint by joint,
translations interpolated linearly). For files written at another frame rate, retargeting, and the
benchmark's speed copies."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from modb_kernel import resample

from modb.motion import Motion


def sampled(motion: Motion, frames: np.ndarray) -> Motion:
    """The motion at fractional frame numbers `frames` (0 to n_frames - 1), an output frame each."""
    rotations, translations = resample.sampled(motion.rotations, motion.translations, frames)
    return replace(motion, rotations=rotations, translations=translations)


def at_fps(motion: Motion, fps: float) -> Motion:
    """The same motion (same duration, last frame kept) at `fps` frames a second."""
    frames = resample.fps_frames(motion.n_frames, motion.fps, fps)
    if fps == motion.fps:
        return motion
    meta = {k: v for k, v in motion.meta.items() if k != "frame_time"}
    return replace(sampled(motion, frames), fps=float(fps), meta=meta)
