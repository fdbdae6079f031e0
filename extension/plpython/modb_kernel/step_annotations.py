"""A clip's steps and the other primitives found from its feet (starts, stops, idle, turning
steps) written as annotation segments of its current version: what modb.annotate_steps does in the
server and a job worker does in its own process (database.py runs the statements on either side;
primitives.py finds them). Segments it writes are marked automatic ("auto": true) and carry their
keyframes (a step's: its touchdowns); a run replaces the automatic segments
of the version and keeps every other (a person's, or one a person edited: the editor drops the
mark; an action's and its lead-in and lead-out, which modb.annotate_action writes)."""

import json

from . import memory
from . import primitives
from . import steps as S
from .database import Statement, StoreError

# The current version, its row locked: an edit of its meta waits, and then sees the new ETag.
CLIP = Statement(
    """SELECT v.version, v.fps, v.n_frames, v.rotations, v.translations, v.meta::text AS meta,
              s.id AS skeleton_id, s.hierarchy::text AS hierarchy, s.joint_map::text AS joint_map
         FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.clip_id = $1 ORDER BY v.version DESC LIMIT 1 FOR UPDATE OF v""",
    ("bigint",),
)
SET_META = Statement(
    "UPDATE modb.clip_versions SET meta = $3::jsonb WHERE clip_id = $1 AND version = $2",
    ("bigint", "int", "text"),
)


def current_version(db, clip):
    """The CLIP row of the clip's current version (locked), or StoreError when it has none."""
    rows = db.run(CLIP, [clip])
    if not rows:
        raise StoreError(
            f"no clip {clip} with a version",
            hint="modb.current_clips lists the stored clips",
            sqlstate="P0002",
        )
    return rows[0]


def motion_of(row):
    """(parents, offsets, rotations, translations, translated, names, joint_map, fps) of a CLIP
    row: what primitives.find and actions.find take."""
    h = json.loads(row["hierarchy"])
    joints = h["joints"]
    return ([j["parent"] for j in joints], [j["offset"] for j in joints], row["rotations"],
            row["translations"], h["translated"], [j["name"] for j in joints],
            json.loads(row["joint_map"]), row["fps"])  # fmt: skip


def segment(name, start, end, keyframes):
    return {"name": name, "start": start, "end": end, "keyframes": keyframes, "auto": True}


def annotate(db, clip):
    """Finds the clip's steps and stores them as its current version's automatic segments; returns
    (version, [segment, ...])."""
    row = current_version(db, clip)
    try:
        found = primitives.find(*motion_of(row))
    except S.StepError as e:
        raise StoreError(
            f"clip {clip}: skeleton {row['skeleton_id']}: {e}",
            hint="complete modb.skeletons.joint_map for it, then find its steps again",
        ) from None
    made = [segment(*found_one) for found_one in found]
    meta = json.loads(row["meta"])
    before = json.dumps(meta, sort_keys=True)
    # a person's segments, and an action's (modb.annotate_action marks them: "hands", "action")
    kept = [a for a in meta.get("annotations", [])
            if not a.get("auto") or "hands" in a or "action" in a]  # fmt: skip
    annotations = sorted(kept + made, key=lambda a: (a["start"], a["end"], a["name"]))
    if annotations:
        meta["annotations"] = annotations
    else:
        meta.pop("annotations", None)
    version = row["version"]
    if json.dumps(meta, sort_keys=True) != before:  # the same steps again: meta and ETag kept
        db.run(SET_META, [clip, version, json.dumps(meta)])
    del row  # the frames: their memory goes back to the system
    memory.release()
    return version, made
