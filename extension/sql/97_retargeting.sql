-- Joint coordinate systems for retargeting (0.15.0): per mapped standard joint a twist axis (toward the
-- joint it moves) and a swing axis (across it), unit vectors in the joint's own frame, and the pose
-- (local rotations) they were read in, which unmapped joints keep (modb_kernel/retarget.py). Derived
-- automatically by the first retargeting to or from the skeleton; editable like the joint map.
CREATE FUNCTION modb.joint_axes_ok(hierarchy jsonb, joint_axes jsonb)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(joint_axes) = 'object'
       AND (NOT joint_axes ? 'joints' OR (
            jsonb_typeof(joint_axes->'joints') = 'object'
            AND NOT EXISTS (
                SELECT FROM jsonb_each(joint_axes->'joints') AS a(standard, axes)
                 WHERE jsonb_typeof(a.axes) <> 'object'
                    OR (a.axes->>'joint') IS NULL
                    OR (a.axes->>'joint') <> ALL (modb.skeleton_joint_names(hierarchy))
                    OR jsonb_typeof(a.axes->'twist') IS DISTINCT FROM 'array'
                    OR jsonb_typeof(a.axes->'swing') IS DISTINCT FROM 'array'
                    OR jsonb_array_length(a.axes->'twist') <> 3
                    OR jsonb_array_length(a.axes->'swing') <> 3)))
       AND (jsonb_typeof(joint_axes->'pose') IS DISTINCT FROM 'array'
            OR jsonb_array_length(joint_axes->'pose') = jsonb_array_length(hierarchy->'joints'));
END;
COMMENT ON FUNCTION modb.joint_axes_ok(jsonb, jsonb) IS
    'True when joint_axes is {} or {"joints": {standard: {"joint" (of the hierarchy), "twist": [x,y,z], "swing": [x,y,z]}}, "pose": null or a [w,x,y,z] per joint}';

ALTER TABLE modb.skeletons ADD COLUMN joint_axes jsonb NOT NULL DEFAULT '{}'
    CONSTRAINT skeletons_joint_axes_check CHECK (modb.joint_axes_ok(hierarchy, joint_axes));
COMMENT ON COLUMN modb.skeletons.joint_axes IS
    'Editable: {"joints": {standard name: {"joint", "twist", "swing"}}, "pose"}: per mapped joint its twist axis (toward the joint it moves) and swing axis (across it), unit vectors in its own frame, and the local rotations of the standing pose they were read in (null: the rest pose); {} until a retargeting derives them';
GRANT UPDATE (joint_axes) ON modb.skeletons TO modb_loader;

-- Retargeting in SQL (0.15.0): a clip's current motion onto another skeleton, stored as a new clip linked
-- to its source, cut into snippets (modb_kernel/retarget.py; `modb retarget` calls this). CREATE OR
-- REPLACE: upgrades include this file when it changes.
CREATE OR REPLACE FUNCTION modb._retarget(clip bigint, skeleton bigint, collection text DEFAULT NULL,
                                         fps float8 DEFAULT NULL, mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel
import json
import numpy as np

R, E = kernel.retarget, kernel.edits
if clip is None or skeleton is None:
    plpy.error("modb.retarget needs a clip and a skeleton")
if fps is not None and E.fps_error(fps):
    plpy.error(f"retargeting clip {clip}: {E.fps_error(fps)}", hint="give a rate in the range, or none for the skeleton's",
               sqlstate="22023")
source = plpy.execute(plpy.prepare(
    """SELECT c.name, modb.collection_path(c.collection_id) AS collection, v.version, v.fps, v.n_frames,
              v.rotations, v.translations, v.meta, s.id AS skeleton_id, s.hierarchy, s.joint_map, s.joint_axes
         FROM modb.clips c JOIN modb.clip_versions v ON v.clip_id = c.id JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE c.id = $1 ORDER BY v.version DESC LIMIT 1""", ["bigint"]), [clip])
if not source:
    plpy.error(f"no clip {clip} with a version", hint="modb.current_clips lists the stored clips",
                   sqlstate="P0002")
source = source[0]
target = plpy.execute(plpy.prepare(
    "SELECT id, hierarchy, joint_map, joint_axes FROM modb.skeletons WHERE id = $1", ["bigint"]), [skeleton])
if not target:
    plpy.error(f"no skeleton {skeleton}", hint="SELECT DISTINCT skeleton_id FROM modb.current_clips lists them",
               sqlstate="P0002")
target = target[0]
first_frame = plpy.execute(plpy.prepare(
    """SELECT v.rotations, v.translations FROM modb.current_clips c
         JOIN modb.clip_versions v USING (clip_id, version) WHERE c.skeleton_id = $1 ORDER BY c.clip_id LIMIT 1""",
    ["bigint"]), [skeleton])
store_axes = plpy.prepare("UPDATE modb.skeletons SET joint_axes = $2::jsonb WHERE id = $1 AND joint_axes = '{}'",
                          ["bigint", "text"])

def frames(rotations, translations):
    r = np.asarray(rotations, dtype=np.float64)
    return r, (np.zeros((r.shape[0], 0, 3)) if translations is None else np.asarray(translations, dtype=np.float64))

def prepared(row, skeleton_id, reference):
    try:
        found = R.skeleton(json.loads(row["hierarchy"]), json.loads(row["joint_map"]), json.loads(row["joint_axes"]))
        ready = R.with_axes(found, reference)
        np.asarray(ready["pose"], dtype=np.float64)  # axes stored before 0.17.0 checked them may not be numbers
        for axes in ready["axes"].values():
            np.asarray([axes["twist"], axes["swing"]], dtype=np.float64)
    except R.RetargetError as e:
        plpy.error(f"skeleton {skeleton_id}: {e}",
                   hint="edit modb.skeletons.joint_map (or joint_axes) for it, then call modb.retarget again")
    except (TypeError, ValueError, KeyError) as e:
        plpy.error(f"skeleton {skeleton_id} has joint_axes that are not numbers ({e})",
                   hint="store them again, or set them to {} to derive them anew")
    if not found["stored_axes"].get("joints"):  # derived now: kept with the skeleton, and editable there
        plpy.execute(store_axes, [skeleton_id, json.dumps(R.stored_form(ready))])
    return ready

rate = fps
if rate is None:  # the rate most of the skeleton's clips have: chains need one rate
    rates = plpy.execute(plpy.prepare(
        "SELECT fps FROM modb.current_clips WHERE skeleton_id = $1 GROUP BY fps ORDER BY count(*) DESC, fps LIMIT 1",
        ["bigint"]), [skeleton])
    rate = rates[0]["fps"] if rates else source["fps"]
# The result's size and rate, refused before any work.
n_result = len(kernel.resample.fps_frames(source["n_frames"], source["fps"], rate))
hierarchy = json.loads(target["hierarchy"])
try:
    E.check_result_size(n_result, len(hierarchy["joints"]), len(hierarchy.get("translated", [])),
                        f"retargeting clip {clip} onto skeleton {skeleton} at {rate:g} fps")
except E.EditError as e:
    plpy.error(str(e), hint="the caps are in docs/reference.md (Limits)", sqlstate="54000")
slow = kernel.terminators.snippet_rate_error(rate)
if slow:
    plpy.error(f"retargeting clip {clip} at {rate:g} fps: {slow}", hint="give a higher fps", sqlstate="22023")
rotations, translations = frames(source["rotations"], source["translations"])
src = prepared(source, source["skeleton_id"], (rotations, translations))
dst = prepared(target, skeleton, frames(first_frame[0]["rotations"], first_frame[0]["translations"]) if first_frame else None)
if rate != source["fps"]:
    wanted = kernel.resample.fps_frames(rotations.shape[0], source["fps"], rate)
    rotations, translations = kernel.resample.sampled(rotations, translations, wanted)
try:
    rotations, translations = R.retarget(src, dst, rotations, translations)
except R.RetargetError as e:
    plpy.error(f"retargeting clip {clip} (skeleton {source['skeleton_id']}) onto skeleton {skeleton}: {e}",
               hint="edit the skeletons' joint_map, then call modb.retarget again")

link = {"clip_id": clip, "version": source["version"], "skeleton_id": skeleton, "fps": rate}
place = collection or f'{source["collection"]} on skeleton {skeleton}'
collection_id = plpy.execute(plpy.prepare("SELECT modb.ensure_collection($1) AS id", ["text"]), [place])[0]["id"]
plpy.execute(plpy.prepare("INSERT INTO modb.clips (collection_id, name) VALUES ($1, $2) ON CONFLICT DO NOTHING",
                          ["bigint", "text"]), [collection_id, source["name"]])
# The new clip's row locked before its newest version is read, as every writer of versions does: a
# second retargeting onto it waits, then finds this one's version and stores nothing.
made = plpy.execute(plpy.prepare("SELECT id FROM modb.clips WHERE collection_id = $1 AND name = $2 FOR NO KEY UPDATE",
                                 ["bigint", "text"]), [collection_id, source["name"]])[0]["id"]
newest = plpy.execute(plpy.prepare(
    "SELECT load_params->'retargeted_from' AS link FROM modb.clip_versions WHERE clip_id = $1 ORDER BY version DESC LIMIT 1",
    ["bigint"]), [made])
if newest and newest[0]["link"] is not None and json.loads(newest[0]["link"]) == link:
    return made  # retargeted so before: nothing new
tags = json.loads(source["meta"]).get("tags", [])
n_frames = rotations.shape[0]
rotations = rotations.astype(np.float32).tolist()
translations = translations.astype(np.float32).tolist() if translations.shape[1] else None
del source, src, dst, first_frame  # the float64 frames: only the lists the insert needs stay
plpy.execute(plpy.prepare(
    """INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations, load_params, meta)
       VALUES ($1, $2, $3, $4, $5, $6, $7::jsonb, $8::jsonb)""",
    ["bigint", "bigint", "float8", "int", "real[]", "real[]", "text", "text"]),
    [made, skeleton, rate, n_frames, rotations, translations,
     json.dumps({"retargeted_from": link}), json.dumps({"retargeted_from": link, "tags": tags})])
del rotations, translations
plpy.execute(plpy.prepare("SELECT modb.build_snippets(clip => $1, mirrored => $2)", ["bigint", "boolean"]),
             [made, bool(mirrored)])
kernel.memory.release()  # a large result's frames are garbage now: their memory goes back to the system
return made
$py$;
COMMENT ON FUNCTION modb._retarget(bigint, bigint, text, float8, boolean) IS
    'Internal: what modb.retarget runs (PL/Python); call that one, whose errors read without Python''s exception names';
REVOKE EXECUTE ON FUNCTION modb._retarget(bigint, bigint, text, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._retarget(bigint, bigint, text, float8, boolean) TO modb_loader;
CREATE FUNCTION modb.retarget(clip bigint, skeleton bigint, collection text DEFAULT NULL,
                                         fps float8 DEFAULT NULL, mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN modb._retarget(clip, skeleton, collection, fps, mirrored);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.retarget(bigint, bigint, text, float8, boolean) IS
    'Retargets the clip''s current motion onto the skeleton (its joint_axes: twist and swing aligned joint by joint, parents first; travel scaled by the legs'' length ratio; the feet as low as the source''s), resampled to fps (1 to 1000; default: the rate most of the skeleton''s clips have; a result past the caps on frames and bytes is refused before any work), and stores it as a clip of collection (default: "SOURCE_COLLECTION on skeleton N") named as the source, linked to it in meta and load_params.retargeted_from, cut into snippets (and mirrored ones when asked); a retargeting done before stores nothing. Returns the new clip''s id';
REVOKE EXECUTE ON FUNCTION modb.retarget(bigint, bigint, text, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.retarget(bigint, bigint, text, float8, boolean) TO modb_loader;
