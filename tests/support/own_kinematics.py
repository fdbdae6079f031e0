"""The tests' own forward kinematics, with scipy's rotations: an oracle for the kernel's."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def rotations_of(wxyz: np.ndarray) -> Rotation:
    """scipy rotations of (..., 4) quaternions stored w first."""
    q = np.asarray(wxyz, dtype=np.float64).reshape(-1, 4)
    return Rotation.from_quat(np.concatenate([q[:, 1:], q[:, :1]], axis=1))


def world_positions(parents, offsets, translated, rotations, translations) -> np.ndarray:
    """(frames, joints, 3) world positions: each joint at its parent's position plus the parent's
    world rotation applied to its offset (or its translation, for a translated joint)."""
    rotations = np.asarray(rotations, dtype=np.float64)
    n = len(rotations)
    slot = {j: k for k, j in enumerate(translated)}
    world_rot, out = [None] * len(parents), np.empty((n, len(parents), 3))
    for j, p in enumerate(parents):
        local = rotations_of(rotations[:, j])
        offset = (
            np.asarray(translations, np.float64)[:, slot[j]]
            if j in slot
            else np.tile(np.asarray(offsets[j], np.float64), (n, 1))
        )
        if p < 0:
            world_rot[j], out[:, j] = local, offset
        else:
            world_rot[j] = world_rot[p] * local
            out[:, j] = out[:, p] + world_rot[p].apply(offset)
    return out


def world_rotation(parents, rotations, joint) -> Rotation:
    """scipy's world rotation of one joint per frame: the local ones multiplied from the top."""
    chain, j = [], joint
    while j >= 0:
        chain.append(j)
        j = parents[j]
    out = Rotation.identity(len(rotations))
    for j in reversed(chain):
        out = out * rotations_of(rotations[:, j])
    return out
