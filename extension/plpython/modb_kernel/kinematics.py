"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""

import numpy as np

from . import quaternion


def world_positions(parents, offsets, rotations, translations=None, translated=()):
    """World positions (frames, joints, 3) of every joint's origin (see world_transforms)."""
    return world_transforms(parents, offsets, rotations, translations, translated)[0]


def world_transforms(parents, offsets, rotations, translations=None, translated=()):
    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.

    parents: parent index per joint (-1 for the root), parents listed before children.
    offsets: (joints, 3) rest offsets from the parent, metres.
    rotations: (frames, joints, 4) unit quaternions relative to the parent.
    translations: (frames, len(translated), 3) local translations that replace the
    offsets of the joints listed in `translated` (joints with position channels).
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    n_frames, n_joints = rotations.shape[:2]
    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()
    if len(translated):
        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)
    positions = np.empty((n_frames, n_joints, 3))
    orientations = np.empty((n_frames, n_joints, 4))
    for j, p in enumerate(parents):
        if p < 0:
            positions[:, j] = local[:, j]
            orientations[:, j] = rotations[:, j]
        else:
            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])
            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])
    return positions, orientations


def rest_positions(parents, offsets):
    """World positions (joints, 3) with every rotation the identity."""
    offsets = np.asarray(offsets, dtype=np.float64)
    out = np.zeros_like(offsets)
    for j, p in enumerate(parents):
        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]
    return out


def pose_jumps(positions, pelvis):
    """Per frame step of world positions (frames, joints, 3): the largest move of a joint relative
    to the pelvis's ground point (metres), so the travel is left out."""
    pose = positions - (positions[:, pelvis] * np.array([1.0, 0.0, 1.0]))[:, None]
    return np.linalg.norm(np.diff(pose, axis=0), axis=-1).max(axis=1)
