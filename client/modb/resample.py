"""A motion sampled at other times: rotations slerped joint by joint (scipy), translations
interpolated linearly. For files written at another frame rate, and the benchmark's speed copies."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from modb.motion import Motion


def sampled(motion: Motion, frames: np.ndarray) -> Motion:
    """The motion at fractional frame numbers `frames` (0 to n_frames - 1), an output frame each."""
    original = np.arange(motion.n_frames, dtype=np.float64)
    frames = np.clip(np.asarray(frames, dtype=np.float64), 0.0, motion.n_frames - 1)
    rotations = np.empty((len(frames), motion.rotations.shape[1], 4))
    for j in range(motion.rotations.shape[1]):
        if motion.n_frames == 1:
            rotations[:, j] = motion.rotations[0, j]
            continue
        xyzw = Slerp(original, Rotation.from_quat(motion.rotations[:, j, [1, 2, 3, 0]]))(
            frames
        ).as_quat()
        rotations[:, j] = xyzw[:, [3, 0, 1, 2]]
    rotations[rotations[:, :, 0] < 0] *= -1  # the model's sign convention: w >= 0
    translations = np.empty((len(frames), motion.translations.shape[1], 3))
    for t in range(motion.translations.shape[1]):
        for c in range(3):
            translations[:, t, c] = np.interp(frames, original, motion.translations[:, t, c])
    return replace(motion, rotations=rotations, translations=translations)


def at_fps(motion: Motion, fps: float) -> Motion:
    """The same motion (same duration, last frame kept) at `fps` frames a second."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if fps == motion.fps:
        return motion
    step = motion.fps / fps
    last = motion.n_frames - 1
    frames = np.minimum(np.arange(int(last / step + 1e-9) + 1) * step, last)
    meta = {k: v for k, v in motion.meta.items() if k != "frame_time"}
    return replace(sampled(motion, frames), fps=float(fps), meta=meta)
