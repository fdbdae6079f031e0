"""Root motion: the character's travel on the top joint, as engines take it.

Unity, Unreal and Blender move a character by its top joint. A synthesized strip places every
snippet's pelvis where the last one ended, so the pelvis path is continuous, but a source's own top
joint is not: Bandai's `joint_Root` stays at its capture origin and jumps metres at every seam. Here
the top joint carries a smooth ground-plane trajectory with heading instead (the pelvis's ground
path and facing, each averaged over a stride so that the sway within a step is not followed), and
the joints below it are re-expressed relative to it, so every joint's world position is unchanged. A
skeleton whose top joint is the pelvis itself (CMU's `root`) gets a new top joint for it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.ndimage import uniform_filter1d

from modb_kernel import kinematics, quaternion
from modb_kernel.terminators import headings

from modb.motion import Joint, Motion, Skeleton

# A stride (two steps) lasts about a second in walking; a moving average over it, run twice (a
# triangular window of two strides), leaves the travel and removes the side-to-side sway.
STRIDE_SECONDS = 1.0


def _smooth(values: np.ndarray, fps: float) -> np.ndarray:
    size = max(1, int(round(STRIDE_SECONDS * fps)))
    once = uniform_filter1d(values, size, axis=0, mode="nearest")
    return uniform_filter1d(once, size, axis=0, mode="nearest")


def trajectory(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Per frame the ground point (x, 0, z) and heading (radians about +Y, 0 facing +Z) of the
    character's travel: the pelvis's, averaged over a stride."""
    sk = motion.skeleton
    positions = motion.world_positions()
    pelvis = positions[:, sk.index(sk.joint_map["pelvis"])]
    ground = _smooth(pelvis * np.array([1.0, 0.0, 1.0]), motion.fps)
    facing = headings(
        positions,
        sk.index(sk.joint_map["left_hip"]),
        sk.index(sk.joint_map["right_hip"]),
        motion.fps,
    )
    return ground, _smooth(np.unwrap(facing), motion.fps)


def _free_name(skeleton: Skeleton) -> str:
    for name in ("root", "root_motion", "modb_root_motion"):
        if name not in skeleton.names:
            return name
    raise ValueError("the skeleton already has joints named root, root_motion and modb_root_motion")


def _with_top_joint(skeleton: Skeleton) -> Skeleton:
    """The skeleton under a new translated top joint at the origin (indices move up by one)."""
    bvh = skeleton.source_format == "bvh"
    top = Joint(
        name=_free_name(skeleton),
        parent=-1,
        offset=(0.0, 0.0, 0.0),
        channels=(
            ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
            if bvh
            else ("TX", "TY", "TZ", "RX", "RY", "RZ")
        ),
        rotation_order="ZXY" if bvh else "XYZ",
    )
    joints = [top] + [replace(j, parent=j.parent + 1) for j in skeleton.joints]
    return replace(skeleton, joints=joints)


def carries_root_motion(skeleton: Skeleton) -> bool:
    """Whether the top joint can carry it: translated, and not the pelvis itself."""
    return skeleton.joints[0].has_position and skeleton.names[0] != skeleton.joint_map.get("pelvis")


def with_root_motion(motion: Motion) -> Motion:
    """The same motion (every joint's world position unchanged) with the travel on the top joint."""
    sk = motion.skeleton
    if not carries_root_motion(sk):
        sk = _with_top_joint(sk)
        rotations = np.concatenate(
            [np.tile([1.0, 0.0, 0.0, 0.0], (motion.n_frames, 1, 1)), motion.rotations], axis=1
        )
        translations = np.concatenate(
            [np.zeros((motion.n_frames, 1, 3)), motion.translations], axis=1
        )
        motion = replace(motion, skeleton=sk, rotations=rotations, translations=translations)
    positions, orientations = kinematics.world_transforms(
        sk.parents, sk.offsets, motion.rotations, motion.translations, sk.translated
    )
    ground, heading = trajectory(motion)
    root = quaternion.about_axis("Y", heading)
    inverse = quaternion.conjugate(root)
    rotations = motion.rotations.copy()
    translations = motion.translations.copy()
    translated = sk.translated
    rotations[:, 0] = quaternion.canonical(root)
    translations[:, translated.index(0)] = ground
    for child in (k for k, j in enumerate(sk.joints) if j.parent == 0):
        rotations[:, child] = quaternion.canonical(
            quaternion.multiply(inverse, orientations[:, child])
        )
        local = quaternion.rotate(inverse, positions[:, child] - ground)
        if child in translated:
            translations[:, translated.index(child)] = local
        elif not np.allclose(local, sk.joints[child].offset, atol=1e-9):
            raise ValueError(
                f"joint {sk.names[child]} has no position channels: the top joint cannot carry "
                "the travel for it"
            )
    return replace(
        motion,
        rotations=rotations,
        translations=translations,
        meta={**motion.meta, "root_motion": sk.names[0]},
    )
