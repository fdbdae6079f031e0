"""The frames a snippet plays, read once per clip version (and mirrored when its snippets are)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import psycopg

from modb_kernel import kinematics, mirror

from modb.clips import read_motion
from modb.motion import Motion, Skeleton


class UnplaceableSkeleton(ValueError):
    pass


@dataclass(frozen=True)
class SourceFrames:
    """A clip version as played: parent-relative rotations, translations and source pelvis path."""

    motion: Motion
    pelvis: np.ndarray  # (frames, 3) world pelvis positions in the source
    root_track: int  # index of the root joint in motion.translations

    @property
    def skeleton(self) -> Skeleton:
        return self.motion.skeleton


def mirrored_motion(motion: Motion) -> Motion:
    """The clip as if captured in a mirror (the same reflection build_snippets uses)."""
    sk = motion.skeleton
    partner = mirror.partner_index(sk.names, sk.mirror_pairs)
    rotations, translations = mirror.mirror(
        sk.parents,
        sk.offsets,
        [j.end_site for j in sk.joints],
        partner,
        motion.rotations,
        motion.translations,
        sk.translated,
    )
    return Motion(
        skeleton=sk,
        fps=motion.fps,
        rotations=np.asarray(rotations, dtype=np.float64),
        translations=np.asarray(translations, dtype=np.float64),
        name=motion.name + " (mirrored)",
        source=motion.source,
        meta=motion.meta,
    )


class FrameLibrary:
    """Clip versions fetched on first use and kept: a strip revisits the same few clips."""

    def __init__(self, conn: psycopg.Connection):
        self.conn = conn  # replaced when the session moves to another node
        self._cache: dict[tuple[int, int, bool], SourceFrames] = {}

    def get(self, clip_id: int, version: int, mirrored: bool) -> SourceFrames:
        key = (clip_id, version, mirrored)
        if key not in self._cache:
            motion = read_motion(self.conn, clip_id, version)
            if mirrored:
                motion = mirrored_motion(motion)
            sk = motion.skeleton
            if 0 not in sk.translated:
                raise UnplaceableSkeleton(
                    f"clip {clip_id}: the root joint {sk.joints[0].name!r} of skeleton {sk.name!r} "
                    f"has no position "
                    "channels, so the clip cannot be moved in the world; load a file whose root "
                    "carries position"
                )
            pelvis = kinematics.world_positions(
                sk.parents, sk.offsets, motion.rotations, motion.translations, sk.translated
            )[:, sk.index(sk.joint_map["pelvis"])]
            self._cache[key] = SourceFrames(motion, pelvis, sk.translated.index(0))
        return self._cache[key]
