"""Independent reference readings of real files (bvhio from PyPI), for comparison with ours."""

from __future__ import annotations

from functools import lru_cache

import bvhio
import numpy as np


@lru_cache(maxsize=None)
def bvhio_world_positions(path: str, unit_m: float) -> tuple[tuple[str, ...], np.ndarray]:
    """(joint names, (frames, joints, 3) world positions in metres) computed by bvhio."""
    root = bvhio.readAsHierarchy(path)
    layout = root.layout()
    n_frames = len(root.Keyframes)
    out = np.empty((n_frames, len(layout), 3))
    for f in range(n_frames):
        root.loadPose(f, recursive=True)
        for k, (joint, _, _) in enumerate(layout):
            out[f, k] = joint.PositionWorld
    return tuple(j.Name for j, _, _ in layout), out * unit_m


def in_order(
    names: list[str], reference_names: tuple[str, ...], positions: np.ndarray
) -> np.ndarray:
    """Our positions re-ordered to the reference's joint order."""
    return positions[:, [names.index(n) for n in reference_names]]
