"""Cutting a clip's current version into snippets and storing them with their terminators: what
modb.build_snippets does in the server, and a job worker does in its own process (database.py runs
the statements on either side). The numbers come from terminators.py and mirror.py."""

import json

import numpy as np

from . import mirror as M
from . import terminators as T
from .database import Statement, StoreError

# The clips to cut: current versions (of the collections' subtree $1, or the clip $2) whose
# snippets,
# mirrored as $3 says, are not stored yet.
TO_CUT = Statement(
    """SELECT v.clip_id, v.version, v.fps, v.n_frames, s.id AS skeleton_id, s.hierarchy::text AS
           hierarchy,
              s.joint_map::text AS joint_map, s.mirror_pairs::text AS mirror_pairs,
                  c.collection_id, c.name,
              modb.skeleton_pose_key(s.hierarchy) AS pose_key
         FROM modb.clip_versions v
         JOIN modb.clips c ON c.id = v.clip_id
         JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.version = (SELECT max(version) FROM modb.clip_versions x WHERE x.clip_id =
            v.clip_id)
          AND ($1::bigint[] IS NULL OR c.collection_id = ANY ($1))
          AND ($2::bigint IS NULL OR c.id = $2)
          AND NOT EXISTS (SELECT FROM modb.snippet_sources ss
                           WHERE ss.clip_id = v.clip_id AND ss.version = v.version AND ss.mirrored
                               = $3)
        ORDER BY v.clip_id""",
    ("bigint[]", "bigint", "boolean"),
)
# Frames are read a slice at a time (and the clip cut chunk by chunk): memory stays bounded whatever
# the clip's length, and no jsonb argument approaches its size limit.
READ_FRAMES = Statement(
    "SELECT rotations[$3:$4] AS rotations, translations[$3:$4] AS translations "
    "FROM modb.clip_versions WHERE clip_id = $1 AND version = $2",
    ("bigint", "int", "int", "int"),
)
DROP_OLD = Statement(
    "DELETE FROM modb.snippet_sources WHERE clip_id = $1 AND version < $2 RETURNING mirrored",
    ("bigint", "int"),
)
BUILT = Statement(
    "SELECT mirrored FROM modb.snippet_sources WHERE clip_id = $1 AND version = $2",
    ("bigint", "int"),
)
ADD_SOURCE = Statement(
    "INSERT INTO modb.snippet_sources (clip_id, version, mirrored, window_frames, stride_frames) "
    "VALUES ($1, $2, $5, $3, $4)",
    ("bigint", "int", "int", "int", "boolean"),
)
ADD_TERMINATORS = Statement(
    """INSERT INTO modb.terminators (clip_id, version, mirrored, frame, heading, pelvis_height,
           positions,
                                     rotations, velocities, angular_velocities, configuration,
                                         features)
       SELECT $1, $2, $4, r.frame, r.heading, r.pelvis_height, r.positions, r.rotations,
           r.velocities,
              r.angular_velocities, r.configuration, cube(r.features)
         FROM jsonb_to_recordset($3::jsonb) AS r(frame int, heading float8, pelvis_height real,
             positions real[],
              rotations real[], velocities real[], angular_velocities real[], configuration
                  real[][], features float8[])
       RETURNING frame, id""",
    ("bigint", "int", "text", "boolean"),
)
ADD_SNIPPETS = Statement(
    """INSERT INTO modb.snippets (clip_id, version, mirrored, first_frame, n_frames,
           collection_id, pose_key, fps,
                                  begin_terminator, end_terminator, begin_features,
                                      net_translation, net_heading,
                                  net_rotation)
       SELECT $1, $2, $8, r.first_frame, $3, $4, $5, $6, r.begin_terminator, r.end_terminator,
           t.features,
              r.net_translation, r.net_heading, r.net_rotation
         FROM jsonb_to_recordset($7::jsonb) AS r(first_frame int, begin_terminator bigint,
             end_terminator bigint,
              net_translation float8[], net_heading float8, net_rotation float8[])
         JOIN modb.terminators t ON t.id = r.begin_terminator
        ORDER BY r.first_frame""",
    ("bigint", "int", "int", "bigint", "text", "float8", "text", "boolean"),
)
# After every clip's snippets exist: futures chain through them.
FILL_FUTURES = Statement("SELECT modb.fill_futures()")


def _flat(a):
    return np.asarray(a, dtype=np.float64).reshape(len(a), -1).tolist()


def _flat_real(a):
    # Rounded to float4 here: a value below float4's range (a resampled clip had 3.8e-51) is then
    # 0, where
    # the real[] input refused it. Normal values round as the input would.
    return np.asarray(a, dtype=np.float32).astype(np.float64).reshape(len(a), -1).tolist()


def _frames(db, row, lo, hi):
    """Rotations and translations (None when no joint has position channels) of frames lo..hi-1."""
    r = db.run(READ_FRAMES, [row["clip_id"], row["version"], lo + 1, hi])[0]
    return (
        np.asarray(r["rotations"], dtype=np.float64),
        None if r["translations"] is None else np.asarray(r["translations"], dtype=np.float64),
    )


def check_window(window_seconds, stride_seconds):
    if not (window_seconds and window_seconds > 0 and stride_seconds and stride_seconds > 0):
        raise StoreError("window_seconds and stride_seconds must be positive")


def cut(db, row, mirrored, window_seconds=0.5, stride_seconds=1.0 / 30):
    """Cuts one TO_CUT row's clip (and its mirror image when `mirrored`, or when its older version
    had one); returns the snippets added. fill_futures() is the caller's, after its last clip."""
    h = json.loads(row["hierarchy"])
    names = [j["name"] for j in h["joints"]]
    try:
        std = T.standard_indices(names, json.loads(row["joint_map"]))
    except T.SkeletonMapError as e:
        raise StoreError(
            f"clip {row['clip_id']} ({row['name']}): skeleton {row['skeleton_id']}: {e}",
            hint="complete modb.skeletons.joint_map for it, then call modb.build_snippets again",
        ) from None
    n_frames = row["n_frames"]
    firsts, length, stride = T.windows(n_frames, row["fps"], window_seconds, stride_seconds)
    slow = T.snippet_rate_error(row["fps"], window_seconds)
    if slow:  # checked here, not left to snippet_sources' constraint, to say what to do
        raise StoreError(
            f"clip {row['clip_id']} ({row['name']}) cannot be cut into snippets: {slow}",
            hint="resample the clip (modb resample, or an edit script's resample) or give a "
            "longer window_seconds",
            sqlstate="22023",
        )
    # A new version replaces the old versions' snippets, and keeps their mirror images if they had
    # them.
    old_flags = {r["mirrored"] for r in db.run(DROP_OLD, [row["clip_id"], row["version"]])}
    existing = {r["mirrored"] for r in db.run(BUILT, [row["clip_id"], row["version"]])}
    parents = [j["parent"] for j in h["joints"]]
    offsets = [j["offset"] for j in h["joints"]]
    added = 0
    for flag in sorted(({bool(mirrored)} | old_flags) - existing):
        db.run(ADD_SOURCE, [row["clip_id"], row["version"], length, stride, flag])
        if len(firsts) == 0:
            continue  # shorter than one snippet: recorded as built, nothing to add
        if flag:
            pairs = json.loads(row["mirror_pairs"])
            if not pairs:
                raise StoreError(
                    f"clip {row['clip_id']} ({row['name']}): skeleton {row['skeleton_id']} has no "
                    "mirror pairs",
                    hint="fill modb.skeletons.mirror_pairs with its [left, right] joints",
                )
            partner = M.partner_index(names, pairs)
            statistics = M.ClipStatistics(parents, offsets, partner, h["translated"])
            for lo in range(0, n_frames, T.CHUNK_FRAMES):
                statistics.add(*_frames(db, row, lo, min(n_frames, lo + T.CHUNK_FRAMES)))
            reflections = statistics.reflections([j["end_site"] for j in h["joints"]])
        ids = {}  # terminator id by frame, for the snippets still to come
        for lo, hi, starts in T.chunks(n_frames, row["fps"], firsts, length):
            rotations, translations = _frames(db, row, lo, hi)
            if flag:
                rotations, translations = M.reflect(
                    reflections, parents, partner, rotations, translations, h["translated"]
                )
            terms = T.compute(
                parents, offsets, rotations, translations, h["translated"], std, row["fps"]
            )
            ids = {f: i for f, i in ids.items() if f >= starts[0]}
            wanted = sorted((set(starts.tolist()) | set((starts + length - 1).tolist())) - set(ids))
            local = [f - lo for f in wanted]
            pick = {
                k: _flat_real(terms[k][local])
                for k in ("positions", "rotations", "velocities", "angular_velocities")
            }
            pick["features"] = _flat(terms["features"][local])
            configuration = (
                terms["configuration"][local].astype(np.float32).astype(np.float64).tolist()
            )
            records = [
                {
                    "frame": f,
                    "heading": float(terms["heading"][f - lo]),
                    "pelvis_height": float(np.float32(terms["pelvis_height"][f - lo])),
                    "positions": pick["positions"][i],
                    "rotations": pick["rotations"][i],
                    "velocities": pick["velocities"][i],
                    "angular_velocities": pick["angular_velocities"][i],
                    "configuration": configuration[i],
                    "features": pick["features"][i],
                }
                for i, f in enumerate(wanted)
            ]
            stored = db.run(
                ADD_TERMINATORS, [row["clip_id"], row["version"], json.dumps(records), flag]
            )
            ids.update({r["frame"]: r["id"] for r in stored})
            # Every snippet's net motion at once (elementwise: what one at a time gave, 20x faster).
            lasts = starts + length - 1
            translation, turn, rotation = T.net_motion(terms, starts - lo, lasts - lo)
            snippets = [
                {
                    "first_frame": first,
                    "begin_terminator": ids[first],
                    "end_terminator": ids[last],
                    "net_translation": moved,
                    "net_heading": turned,
                    "net_rotation": turning,
                }
                for first, last, moved, turned, turning in zip(
                    starts.tolist(),
                    lasts.tolist(),
                    translation.tolist(),
                    turn.tolist(),
                    rotation.tolist(),
                )
            ]
            db.run(
                ADD_SNIPPETS,
                [
                    row["clip_id"],
                    row["version"],
                    length,
                    row["collection_id"],
                    row["pose_key"],
                    row["fps"],
                    json.dumps(snippets),
                    flag,
                ],
            )
            added += len(snippets)
    return added


def cut_clip(db, clip_id, mirrored=False):
    """Cuts the clip's current version, and its mirror image too when `mirrored` (or when an older
    version had one), as `modb load --mirror` does; its futures filled. Returns the snippets
    added."""
    added = 0
    for flag in (False, True) if mirrored else (False,):
        added += sum(cut(db, row, flag) for row in db.run(TO_CUT, [None, clip_id, flag]))
    db.run(FILL_FUTURES)
    return added
