"""Frames at other times: rotations slerped joint by joint, translations interpolated linearly. The
one implementation for the client (file rates, speed copies, retargeting, edit scripts) and the
server (modb.retarget, edit scripts). Plain numpy (server and client)."""

import numpy as np

from . import quaternion


def sampled(rotations, translations, frames):
    """(rotations, translations) at fractional frame numbers `frames` (clipped to the clip)."""
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    n = rotations.shape[0]
    frames = np.clip(np.asarray(frames, dtype=np.float64), 0.0, n - 1)
    before = np.minimum(np.floor(frames).astype(int), max(n - 2, 0))
    after = np.minimum(before + 1, n - 1)
    alpha = (frames - before)[:, None, None]
    a, b = rotations[before], rotations[after]
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -b, b)  # the shorter way round
    step = quaternion.multiply(quaternion.conjugate(a), b)
    out_rotations = quaternion.canonical(
        quaternion.multiply(a, quaternion.power(step, alpha[..., 0][..., None]))
    )
    out_translations = translations[before] + alpha * (translations[after] - translations[before])
    return out_rotations, out_translations


def fps_frames(n_frames, fps, new_fps):
    """The fractional source frames of the same clip at new_fps (same start, last frame kept)."""
    if not new_fps > 0:
        raise ValueError(f"fps must be positive, got {new_fps}")
    step = fps / new_fps
    last = n_frames - 1
    return np.minimum(np.arange(int(last / step + 1e-9) + 1) * step, last)
