"""Checks the database applies to stored frames (used by CHECK constraints)."""

import numpy as np


def unit_quaternions_ok(rotations, tolerance):
    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""
    try:
        q = np.asarray(rotations, dtype=np.float64)
    except (TypeError, ValueError):  # NULL elements arrive as None
        return False
    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):
        return False
    q = q.reshape(-1, 4)
    return bool(
        np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0)
    )


def finite_ok(values):
    """True when the (nested) array has no NULL (None), NaN or infinite element."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return bool(np.all(np.isfinite(a)))
