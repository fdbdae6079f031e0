"""Retargeting a motion in memory onto another skeleton (modb_kernel.retarget does the numerics, as
modb.retarget does in the database, which stores the result as a new clip): for edit scripts, tests
and callers of the Python API."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from modb_kernel import retarget as kernel

from modb.motion import Motion, Skeleton
from modb.resample import at_fps


class RetargetError(ValueError):
    pass


def prepared(skeleton: Skeleton, reference: Motion | None = None) -> dict[str, Any]:
    """The skeleton as modb_kernel.retarget takes it, with its axes (stored, else derived from the
    frames of `reference`, a clip on it, else from its rest pose when it stands)."""
    found = kernel.skeleton(skeleton.hierarchy_json(), skeleton.joint_map, skeleton.joint_axes)
    frame = None if reference is None else (reference.rotations, reference.translations)
    try:
        return kernel.with_axes(found, frame)
    except kernel.RetargetError as e:
        raise RetargetError(f"skeleton {skeleton.name or '(unnamed)'}: {e}") from None


def retarget_motion(
    motion: Motion,
    destination: Skeleton,
    fps: float | None = None,
    destination_reference: Motion | None = None,
) -> Motion:
    """The motion on `destination`, at `fps` (default: its own rate). `destination_reference`: a
    clip on the destination, for its axes when its rest pose does not stand."""
    if fps is not None and fps != motion.fps:
        motion = at_fps(motion, fps)
    rotations, translations = kernel.retarget(
        prepared(motion.skeleton, motion),
        prepared(destination, destination_reference),
        motion.rotations,
        motion.translations,
    )
    return replace(motion, skeleton=destination, rotations=rotations, translations=translations)
