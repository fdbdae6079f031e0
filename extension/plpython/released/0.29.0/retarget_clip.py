"""A stored clip retargeted onto another skeleton and stored as a clip linked to its source, cut
       into
snippets: what modb.retarget does in the server and a job worker does in its own process
    (database.py
runs the statements on either side; retarget.py does the numerics)."""

import json

import numpy as np

from . import edits as E
from . import memory
from . import resample
from . import retarget as R
from . import snippet_cut
from . import terminators as T
from .database import Statement, StoreError

SOURCE = Statement(
    """SELECT c.name, modb.collection_path(c.collection_id) AS collection, v.version, v.fps,
           v.n_frames,
              v.rotations, v.translations, v.meta::text AS meta, s.id AS skeleton_id,
                  s.hierarchy::text AS hierarchy,
              s.joint_map::text AS joint_map, s.joint_axes::text AS joint_axes
         FROM modb.clips c JOIN modb.clip_versions v ON v.clip_id = c.id JOIN modb.skeletons s ON
             s.id = v.skeleton_id
        WHERE c.id = $1 ORDER BY v.version DESC LIMIT 1""",
    ("bigint",),
)
TARGET = Statement(
    "SELECT id, hierarchy::text AS hierarchy, joint_map::text AS joint_map, "
    "joint_axes::text AS joint_axes "
    "FROM modb.skeletons WHERE id = $1",
    ("bigint",),
)
# A clip on the skeleton: the frames its axes are derived from when none are stored.
REFERENCE_CLIP = Statement(
    """SELECT v.rotations, v.translations FROM modb.current_clips c
         JOIN modb.clip_versions v USING (clip_id, version)
        WHERE c.skeleton_id = $1 ORDER BY c.clip_id LIMIT 1""",
    ("bigint",),
)
STORE_AXES = Statement(
    "UPDATE modb.skeletons SET joint_axes = $2::jsonb WHERE id = $1 AND joint_axes = '{}'",
    ("bigint", "text"),
)
USUAL_RATE = Statement(  # the rate most of the skeleton's clips have: chains need one rate
    "SELECT fps FROM modb.current_clips WHERE skeleton_id = $1 "
    "GROUP BY fps ORDER BY count(*) DESC, fps LIMIT 1",
    ("bigint",),
)
ENSURE_COLLECTION = Statement("SELECT modb.ensure_collection($1) AS id", ("text",))
ADD_CLIP = Statement(
    "INSERT INTO modb.clips (collection_id, name) VALUES ($1, $2) ON CONFLICT DO NOTHING",
    ("bigint", "text"),
)
# The new clip's row locked before its newest version is read, as every writer of versions does: a
# second retargeting onto it waits, then finds this one's version and stores nothing.
LOCK_CLIP = Statement(
    "SELECT id FROM modb.clips WHERE collection_id = $1 AND name = $2 FOR NO KEY UPDATE",
    ("bigint", "text"),
)
NEWEST_LINK = Statement(
    "SELECT (load_params->'retargeted_from')::text AS link FROM modb.clip_versions "
    "WHERE clip_id = $1 "
    "ORDER BY version DESC LIMIT 1",
    ("bigint",),
)
ADD_VERSION = Statement(
    """INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations,
           translations, load_params, meta)
       VALUES ($1, $2, $3, $4, $5, $6, $7::jsonb, $8::jsonb)""",
    ("bigint", "bigint", "float8", "int", "real[]", "real[]", "text", "text"),
)


def frames(rotations, translations):
    r = np.asarray(rotations, dtype=np.float64)
    return r, (
        np.zeros((r.shape[0], 0, 3))
        if translations is None
        else np.asarray(translations, dtype=np.float64)
    )


def _prepared(db, row, skeleton_id, reference):
    try:
        found = R.skeleton(
            json.loads(row["hierarchy"]),
            json.loads(row["joint_map"]),
            json.loads(row["joint_axes"]),
        )
        ready = R.with_axes(found, reference)
        np.asarray(
            ready["pose"], dtype=np.float64
        )  # axes stored before 0.17.0 checked them may not be numbers
        for axes in ready["axes"].values():
            np.asarray([axes["twist"], axes["swing"]], dtype=np.float64)
    except R.RetargetError as e:
        raise StoreError(
            f"skeleton {skeleton_id}: {e}",
            hint="edit modb.skeletons.joint_map (or joint_axes) for it, then call modb.retarget "
            "again",
        ) from None
    except (TypeError, ValueError, KeyError) as e:
        raise StoreError(
            f"skeleton {skeleton_id} has joint_axes that are not numbers ({e})",
            hint="store them again, or set them to {} to derive them anew",
        ) from None
    if not found["stored_axes"].get(
        "joints"
    ):  # derived now: kept with the skeleton, and editable there
        db.run(STORE_AXES, [skeleton_id, json.dumps(R.stored_form(ready))])
    return ready


def retarget_clip(db, clip, skeleton, collection=None, fps=None, mirrored=False):
    """Retargets the clip's current motion onto the skeleton and stores it (see modb.retarget's
    comment); returns the new clip's id. A retargeting done before stores nothing."""
    if clip is None or skeleton is None:
        raise StoreError("modb.retarget needs a clip and a skeleton")
    if fps is not None and E.fps_error(fps):
        raise StoreError(
            f"retargeting clip {clip}: {E.fps_error(fps)}",
            hint="give a rate in the range, or none for the skeleton's",
            sqlstate="22023",
        )
    source = db.run(SOURCE, [clip])
    if not source:
        raise StoreError(
            f"no clip {clip} with a version",
            hint="modb.current_clips lists the stored clips",
            sqlstate="P0002",
        )
    source = source[0]
    target = db.run(TARGET, [skeleton])
    if not target:
        raise StoreError(
            f"no skeleton {skeleton}",
            hint="SELECT DISTINCT skeleton_id FROM modb.current_clips lists them",
            sqlstate="P0002",
        )
    target = target[0]
    rate = fps
    if rate is None:
        rates = db.run(USUAL_RATE, [skeleton])
        rate = rates[0]["fps"] if rates else source["fps"]
    # The result's size and rate, refused before any work.
    n_result = len(resample.fps_frames(source["n_frames"], source["fps"], rate))
    hierarchy = json.loads(target["hierarchy"])
    try:
        E.check_result_size(
            n_result,
            len(hierarchy["joints"]),
            len(hierarchy.get("translated", [])),
            f"retargeting clip {clip} onto skeleton {skeleton} at {rate:g} fps",
        )
    except E.EditError as e:
        raise StoreError(
            str(e), hint="the caps are in docs/reference.md (Limits)", sqlstate="54000"
        ) from None
    slow = T.snippet_rate_error(rate)
    if slow:
        raise StoreError(
            f"retargeting clip {clip} at {rate:g} fps: {slow}",
            hint="give a higher fps",
            sqlstate="22023",
        )
    rotations, translations = frames(source["rotations"], source["translations"])
    src = _prepared(db, source, source["skeleton_id"], (rotations, translations))
    reference = None
    if not json.loads(target["joint_axes"]).get("joints"):  # stored axes need no frames
        found = db.run(REFERENCE_CLIP, [skeleton])
        reference = frames(found[0]["rotations"], found[0]["translations"]) if found else None
    dst = _prepared(db, target, skeleton, reference)
    if rate != source["fps"]:
        wanted = resample.fps_frames(rotations.shape[0], source["fps"], rate)
        rotations, translations = resample.sampled(rotations, translations, wanted)
    try:
        rotations, translations = R.retarget(src, dst, rotations, translations)
    except R.RetargetError as e:
        raise StoreError(
            f"retargeting clip {clip} (skeleton {source['skeleton_id']}) onto skeleton "
            f"{skeleton}: {e}",
            hint="edit the skeletons' joint_map, then call modb.retarget again",
        ) from None

    link = {"clip_id": clip, "version": source["version"], "skeleton_id": skeleton, "fps": rate}
    place = collection or f"{source['collection']} on skeleton {skeleton}"
    collection_id = db.run(ENSURE_COLLECTION, [place])[0]["id"]
    db.run(ADD_CLIP, [collection_id, source["name"]])
    made = db.run(LOCK_CLIP, [collection_id, source["name"]])[0]["id"]
    newest = db.run(NEWEST_LINK, [made])
    if newest and newest[0]["link"] is not None and json.loads(newest[0]["link"]) == link:
        return made  # retargeted so before: nothing new
    tags = json.loads(source["meta"]).get("tags", [])
    n_frames = rotations.shape[0]
    rotations = rotations.astype(np.float32).tolist()
    translations = translations.astype(np.float32).tolist() if translations.shape[1] else None
    del source, src, dst, reference  # the float64 frames: only the lists the insert needs stay
    db.run(
        ADD_VERSION,
        [
            made,
            skeleton,
            rate,
            n_frames,
            rotations,
            translations,
            json.dumps({"retargeted_from": link}),
            json.dumps({"retargeted_from": link, "tags": tags}),
        ],
    )
    del rotations, translations
    snippet_cut.cut_clip(db, made, mirrored)
    memory.release()  # a large result's frames are garbage: their memory goes back to the system
    return made
