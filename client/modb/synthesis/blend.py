"""Seam blending (Settings.blend_frames): the jump at a seam spread over the frames after it."""

from __future__ import annotations

import numpy as np

from modb_kernel import quaternion

from .chain import Frame


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
