"""Seam blending (Settings.blend_frames): the jump at a seam spread over the frames after it."""

from __future__ import annotations

import numpy as np

from modb_kernel import quaternion
from modb_kernel.standing import slerp

from .chain import Frame

CROSS_FADE_SECONDS = 0.2  # a piece replaced while it plays fades into the new one over this


def blend_seam(
    previous_last: Frame | None, rotations: np.ndarray, translations: np.ndarray, blend_frames: int
) -> tuple[np.ndarray, np.ndarray]:
    """Optional seam blending: the jump fades out linearly over the next blend_frames frames.

    The jump is between the previous snippet's last frame and this one's first (which it replaces).
    """
    n = min(blend_frames, len(rotations) - 2)  # the last frame stays as placed: the next seam
    if previous_last is None or n <= 0:
        return rotations, translations
    jump = quaternion.multiply(previous_last.rotations, quaternion.conjugate(rotations[0]))
    shift = previous_last.translations - translations[0]  # the arrays are _choose's own copies
    for k in range(1, n + 1):
        weight = 1.0 - k / (n + 1)
        rotations[k] = quaternion.canonical(
            quaternion.multiply(quaternion.power(jump, weight), rotations[k])
        )
        translations[k] = translations[k] + weight * shift
    return rotations, translations


def cross_fade(
    old: tuple[np.ndarray, np.ndarray],
    new: tuple[np.ndarray, np.ndarray],
    start: int,
    n: int,
) -> tuple[np.ndarray, np.ndarray]:
    """A piece replaced while it plays: `new`'s (rotations, translations) with its frames start to
    start + n - 1 faded in from `old`'s same frames (both from the same first frame), the weight
    easing in on a half cosine; new's own frames before and after. The avatars use it when a new
    goal replans the piece playing."""
    rotations, translations = np.array(new[0]), np.array(new[1])  # copies: faded here
    fade = slice(start, start + n)
    weight = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n + 1) / (n + 1))
    shape = rotations[fade].shape
    rotations[fade] = slerp(np.reshape(old[0][fade], (-1, 4)), rotations[fade].reshape(-1, 4),
                            np.repeat(weight, shape[1])).reshape(shape)  # fmt: skip
    translations[fade] = old[1][fade] + weight[:, None, None] * (translations[fade] - old[1][fade])
    return rotations, translations
