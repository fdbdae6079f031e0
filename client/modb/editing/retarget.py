"""Retargeting stored clips onto another skeleton (modb_kernel.retarget does the numerics):
resampled to the destination's frame rate first (chains need one rate), stored as new clips linked
to their source
in meta, never as a new version of the source (which would replace its snippets)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import psycopg
from modb_kernel import retarget as kernel

from modb.clips import read_motion
from modb.motion import Motion, Skeleton
from modb.resample import at_fps


class RetargetError(ValueError):
    pass


def axes(skeleton: Skeleton, reference: Motion | None = None) -> tuple[dict[str, Any], Any]:
    """Each mapped standard joint's twist and swing axes, and the local rotations of the standing
    pose they come from: the rest pose when it stands, else the first frame of `reference` (a clip
    on this skeleton)."""
    missing = [s for s in ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee",
                           "left_ankle", "right_ankle") if s not in skeleton.joint_map]  # fmt: skip
    if missing:
        raise RetargetError(
            f"skeleton {skeleton.name or '(unnamed)'}: its joint map lacks {', '.join(missing)}; "
            "edit it (PUT /api/skeletons/ID/maps, or UPDATE modb.skeletons SET joint_map = ...)"
        )
    shape = (skeleton.parents, skeleton.offsets, skeleton.names, skeleton.joint_map)
    frame = None
    if not kernel.upright(*shape):
        if reference is None:
            raise RetargetError(
                f"skeleton {skeleton.name or '(unnamed)'}: its rest pose does not stand, and it "
                "has no clip to take a standing pose from; load one first"
            )
        frame = (reference.rotations[0], reference.translations[0], skeleton.translated)
    found = kernel.joint_axes(
        skeleton.parents,
        skeleton.offsets,
        [j.end_site for j in skeleton.joints],
        skeleton.names,
        skeleton.joint_map,
        frame,
    )
    pose = np.tile([1.0, 0.0, 0.0, 0.0], (len(skeleton.joints), 1)) if frame is None else frame[0]
    return found, pose


def _kernel_skeleton(skeleton: Skeleton, reference: Motion | None) -> dict[str, Any]:
    return {
        "parents": skeleton.parents,
        "offsets": skeleton.offsets,
        "end_sites": [j.end_site for j in skeleton.joints],
        "names": skeleton.names,
        "joint_map": skeleton.joint_map,
        "translated": skeleton.translated,
        **dict(zip(("axes", "pose"), axes(skeleton, reference), strict=True)),
    }


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
        _kernel_skeleton(motion.skeleton, motion),
        _kernel_skeleton(destination, destination_reference),
        motion.rotations,
        motion.translations,
    )
    return replace(motion, skeleton=destination, rotations=rotations, translations=translations)


def reference_clip(conn: psycopg.Connection, skeleton_id: int) -> Motion | None:
    """The skeleton's first stored clip (its first frame stands for the skeleton's pose)."""
    row = conn.execute(
        "SELECT min(clip_id) FROM modb.current_clips WHERE skeleton_id = %s", [skeleton_id]
    ).fetchone()
    return read_motion(conn, row[0]) if row[0] is not None else None


def read_skeleton(conn: psycopg.Connection, skeleton_id: int) -> Skeleton:
    row = conn.execute(
        "SELECT name, hierarchy, joint_map, mirror_pairs FROM modb.skeletons WHERE id = %s",
        [skeleton_id],
    ).fetchone()
    if row is None:
        raise RetargetError(f"no skeleton {skeleton_id} (`modb list` shows the clips' skeletons)")
    name, hierarchy, joint_map, mirror_pairs = row
    return Skeleton.from_row(hierarchy, joint_map, mirror_pairs, name=name)


def usual_fps(conn: psycopg.Connection, skeleton_id: int) -> float | None:
    """The frame rate most of the skeleton's current clips have (None: it has none)."""
    rates = Counter(
        fps
        for (fps,) in conn.execute(
            "SELECT fps FROM modb.current_clips WHERE skeleton_id = %s", [skeleton_id]
        )
    )
    return rates.most_common(1)[0][0] if rates else None


def retarget_clip(
    conn: psycopg.Connection,
    clip_id: int,
    skeleton_id: int,
    collection: str,
    fps: float | None = None,
    snippets: bool = True,
    mirrored: bool = False,
) -> tuple[Any, Motion]:
    """Stores the clip's current motion retargeted onto the skeleton as a clip of `collection`
    (same name), linked to its source in meta; returns (Stored, the motion stored)."""
    from modb.loader.ingest import store_motion

    source = read_motion(conn, clip_id)
    destination = read_skeleton(conn, skeleton_id)
    rate = fps or usual_fps(conn, skeleton_id) or source.fps
    motion = retarget_motion(source, destination, rate, reference_clip(conn, skeleton_id))
    link = {
        "clip_id": clip_id,
        "version": source.meta.get("version"),
        "skeleton_id": skeleton_id,
        "fps": rate,
    }
    motion = replace(motion, meta={"retargeted_from": link})
    stored = store_motion(
        conn,
        motion,
        collection,
        key=f"retarget:{clip_id}:{link['version']}:{skeleton_id}:{rate}",
        snippets=snippets,
        mirrored=mirrored,
        meta={"retargeted_from": link, "tags": source.meta.get("tags", [])},
    )
    return stored, motion


def retarget_clips(
    conn: psycopg.Connection,
    clip_ids: list[int],
    skeleton_id: int,
    collection: str,
    fps: float | None = None,
    mirrored: bool = False,
    progress: Callable[[int, Any], None] | None = None,
) -> list[Any]:
    """Each clip retargeted (one transaction each, as a load is)."""
    out = []
    for clip_id in clip_ids:
        stored, _ = retarget_clip(conn, clip_id, skeleton_id, collection, fps, mirrored=mirrored)
        out.append(stored)
        if progress:
            progress(clip_id, stored)
    return out
