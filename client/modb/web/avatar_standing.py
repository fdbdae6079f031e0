"""The avatar standing on the page before its first goal, in motion matching: the first frame of
the slowest snippet of the default pool (the largest pool of one skeleton and rate, which the
Avatar draws from when no collection is chosen), placed as the Avatar places a walk's first
snippet: its pelvis above the origin, facing +Z. One query; the walk still starts there."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import psycopg

from modb_kernel import kinematics

from modb.motion import Skeleton
from modb.synthesis.chain import Frame
from modb.synthesis.placement import Placement, place_root

from .avatar_messages import frame_message

log = logging.getLogger("modb.web")

# The slowest snippet first (ground travel per frame, then turn), never a mirror image (its frames
# are not stored): its begin heading, its clip's frame and skeleton.
STANDING = """
WITH pool AS (SELECT pose_key, fps FROM modb.snippet_pools() LIMIT 1),
slowest AS (
    SELECT s.clip_id, s.version, s.first_frame, s.begin_terminator
      FROM pool p JOIN modb.snippets s ON s.pose_key = p.pose_key AND s.fps = p.fps
     WHERE NOT s.mirrored
     ORDER BY sqrt(s.net_translation[1] ^ 2 + s.net_translation[3] ^ 2) / s.n_frames,
              abs(s.net_heading), s.id
     LIMIT 1)
SELECT k.id, k.name, k.hierarchy, k.joint_map, k.mirror_pairs, b.heading,
       v.rotations[w.first_frame + 1 : w.first_frame + 1],
       v.translations[w.first_frame + 1 : w.first_frame + 1]
  FROM slowest w
  JOIN modb.terminators b ON b.id = w.begin_terminator
  JOIN modb.clip_versions v ON v.clip_id = w.clip_id AND v.version = w.version
  JOIN modb.skeletons k ON k.id = v.skeleton_id
"""

ORIGIN = Placement((0.0, 0.0, 0.0), 0.0)  # where a new Avatar starts: the origin, facing +Z


def standing_messages(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """The skeleton and standing frame messages; none when the database has no snippet (or its
    root cannot be placed: the walk says why at the first click)."""
    try:
        with conn.transaction():  # a savepoint: the connection goes on after a failure
            row = conn.execute(STANDING).fetchone()
    except psycopg.Error:  # the page shows no one until the first click
        log.warning("the avatar's standing pose could not be read", exc_info=True)
        return []
    if row is None or row[7] is None:
        return []
    skeleton_id, name, hierarchy, joint_map, mirror_pairs, heading, rotations, translations = row
    sk = Skeleton.from_row(hierarchy, joint_map, mirror_pairs, name)
    if 0 not in sk.translated or "pelvis" not in sk.joint_map:
        return []
    r = np.asarray(rotations, dtype=np.float64).reshape(1, len(sk.joints), 4)
    t = np.asarray(translations, dtype=np.float64).reshape(1, len(sk.translated), 3)
    pelvis = kinematics.world_positions(sk.parents, sk.offsets, r, t, sk.translated)[
        0, sk.index(sk.joint_map["pelvis"])
    ]
    root = sk.translated.index(0)
    r[:, 0], t[:, root] = place_root(
        r[:, 0], t[:, root], pelvis * np.array([1.0, 0.0, 1.0]), heading, ORIGIN
    )
    skeleton = {
        "type": "skeleton",
        "id": skeleton_id,
        "hierarchy": hierarchy,
        "pelvis": sk.joint_map["pelvis"],
    }
    return [skeleton, frame_message(Frame(0, 0, r[0], t[0]))]
