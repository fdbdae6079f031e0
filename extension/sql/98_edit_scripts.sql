-- Edit scripts (0.15.0): named JSON lists of commands (modb_kernel/edits.py lists them) applied in one
-- call to clips, each result a new version whose load_params.edit_script records what made it, so it can
-- be replayed. No selection reads this table.
CREATE TABLE modb.edit_scripts (
    name       text PRIMARY KEY CHECK (name ~ '^[^[:cntrl:]]{1,200}$'),
    commands   jsonb NOT NULL CHECK (jsonb_typeof(commands) = 'array' AND jsonb_array_length(commands) > 0),
    comment    text,
    created_at timestamptz NOT NULL DEFAULT now(),
    created_by name NOT NULL DEFAULT current_user
);
COMMENT ON TABLE modb.edit_scripts IS
    'Edit scripts: [{"op": "mirror" | "trim" (start, end) | "smooth" (seconds) | "resample" (fps) | "time_stretch" (factor) | "copy_joints" (clip, joints, start, end, source_start, blend) | "retarget" (skeleton)}, ...], applied in order by modb.apply_edit_script';
SELECT pg_catalog.pg_extension_config_dump('modb.edit_scripts', '');
GRANT SELECT ON modb.edit_scripts TO modb_reader;
GRANT INSERT (name, commands, comment), UPDATE (commands, comment), DELETE ON modb.edit_scripts TO modb_loader;

CREATE OR REPLACE FUNCTION modb._apply_edit_script(script text, clips bigint[])
RETURNS TABLE (clip_id bigint, version int, n_frames int, snippets bigint)
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel
import json
import numpy as np

R, E, T = kernel.retarget, kernel.edits, kernel.terminators
found = plpy.execute(plpy.prepare("SELECT commands FROM modb.edit_scripts WHERE name = $1", ["text"]), [script])
if not found:
    plpy.error(f'no edit script "{script}"', hint="SELECT name FROM modb.edit_scripts lists them",
               sqlstate="P0002")
commands = json.loads(found[0]["commands"])
problems = E.script_errors(commands)
if problems:  # a row stored before 0.17.0 checked scripts
    plpy.error(f'edit script "{script}" cannot run: {"; ".join(problems)}',
               hint="save it again with commands that modb.edit_scripts describes")
# Each clip once (a clip named twice, or also inside a named collection, is edited once), in the
# order given; their rows locked in id order first, as every writer of a clip's versions does, so
# two scripts on one clip run one after the other (each on the other's result) and never deadlock.
targets = list(dict.fromkeys(c for c in (clips or []) if c is not None))
plpy.execute(plpy.prepare("SELECT FROM modb.clips WHERE id = ANY ($1) ORDER BY id FOR NO KEY UPDATE",
                          ["bigint[]"]), [targets])
read_size = plpy.prepare(
    """SELECT v.version, v.fps, v.n_frames, jsonb_array_length(s.hierarchy->'joints') AS joints,
              coalesce(jsonb_array_length(s.hierarchy->'translated'), 0) AS translated
         FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.clip_id = $1 ORDER BY v.version DESC LIMIT 1""", ["bigint"])
skeleton_size = plpy.prepare(
    """SELECT jsonb_array_length(hierarchy->'joints') AS joints,
              coalesce(jsonb_array_length(hierarchy->'translated'), 0) AS translated
         FROM modb.skeletons WHERE id = $1""", ["bigint"])
read_clip = plpy.prepare(
    """SELECT v.version, v.fps, v.rotations, v.translations, v.meta, s.id AS skeleton_id, s.hierarchy,
              s.joint_map, s.joint_axes, s.mirror_pairs,
              EXISTS (SELECT FROM modb.snippet_sources ss WHERE ss.clip_id = v.clip_id AND ss.mirrored) AS mirrored
         FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.clip_id = $1 ORDER BY v.version DESC LIMIT 1""", ["bigint"])
read_skeleton = plpy.prepare(
    """SELECT s.hierarchy, s.joint_map, s.joint_axes, s.mirror_pairs,
              (SELECT v.rotations FROM modb.current_clips c JOIN modb.clip_versions v USING (clip_id, version)
                WHERE c.skeleton_id = s.id ORDER BY c.clip_id LIMIT 1) AS rotations,
              (SELECT v.translations FROM modb.current_clips c JOIN modb.clip_versions v USING (clip_id, version)
                WHERE c.skeleton_id = s.id ORDER BY c.clip_id LIMIT 1) AS translations
         FROM modb.skeletons s WHERE s.id = $1""", ["bigint"])
add_version = plpy.prepare(
    """INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations, load_params, meta)
       VALUES ($1, $2, $3, $4, $5, $6, $7::jsonb, $8::jsonb) RETURNING version""",
    ["bigint", "bigint", "float8", "int", "real[]", "real[]", "text", "text"])
cut = plpy.prepare("SELECT modb.build_snippets(clip => $1, mirrored => $2) AS added", ["bigint", "boolean"])
count = plpy.prepare("SELECT count(*) AS n FROM modb.snippets WHERE clip_id = $1", ["bigint"])

def frames(rotations, translations):
    r = np.asarray(rotations, dtype=np.float64)
    return r, (np.zeros((r.shape[0], 0, 3)) if translations is None else np.asarray(translations, dtype=np.float64))

def skeleton_of(row, skeleton_id):
    try:
        sk = R.skeleton(json.loads(row["hierarchy"]), json.loads(row["joint_map"]), json.loads(row["joint_axes"]),
                        json.loads(row["mirror_pairs"]))
    except (TypeError, ValueError) as e:  # joint_axes stored before 0.17.0 checked them
        plpy.error(f"skeleton {skeleton_id} has joint_axes that are not numbers ({e})",
                   hint="store them again, or set them to {} to derive them anew")
    sk["id"] = skeleton_id
    return sk

def clip_of(row):
    r, t = frames(row["rotations"], row["translations"])
    return {"skeleton": skeleton_of(row, row["skeleton_id"]), "fps": row["fps"], "rotations": r, "translations": t}

def fetch(clip_id):
    if not isinstance(clip_id, int):
        return None
    rows = plpy.execute(read_clip, [clip_id])
    return clip_of(rows[0]) if rows else None

def fetch_skeleton(skeleton_id):
    if not isinstance(skeleton_id, int):
        return None
    rows = plpy.execute(read_skeleton, [skeleton_id])
    if not rows:
        return None
    reference = None if rows[0]["rotations"] is None else frames(rows[0]["rotations"], rows[0]["translations"])
    return skeleton_of(rows[0], skeleton_id), reference

def check_size(clip_id, size):
    """The result's frames, bytes and rate from the script's parameters, refused before any work."""
    n_frames, fps, largest = E.result_frames(commands, size["n_frames"], size["fps"])
    joints, translated = size["joints"], size["translated"]
    for skeleton in {c["skeleton"] for c in commands if c["op"] == "retarget"}:  # the largest
        other = plpy.execute(skeleton_size, [skeleton])
        if other:
            joints, translated = max(joints, other[0]["joints"]), max(translated, other[0]["translated"])
    what = "the result" if largest <= n_frames else "a step"
    try:
        E.check_result_size(largest, joints, translated, f'edit script "{script}" on clip {clip_id}: {what}')
    except E.EditError as e:
        plpy.error(str(e), hint="the caps are in docs/reference.md (Limits)", sqlstate="54000")
    slow = T.snippet_rate_error(fps)
    if slow:
        plpy.error(f'edit script "{script}" on clip {clip_id}: the result at {fps:g} fps: {slow}',
                   hint="resample to a higher rate in the script", sqlstate="22023")

for clip_id in targets:
    rows = plpy.execute(read_size, [clip_id])
    if not rows:
        plpy.error(f"no clip {clip_id} with a version", hint="modb.current_clips lists the stored clips",
                   sqlstate="P0002")
    check_size(clip_id, rows[0])

results = []  # returned whole: an error raised inside a generator would lose its message
for clip_id in targets:
    row = plpy.execute(read_clip, [clip_id])[0]
    clip = clip_of(row)
    try:
        edited = E.apply(clip, commands, fetch, fetch_skeleton)
    except E.EditError as e:
        plpy.error(f'edit script "{script}" on clip {clip_id}: {e}', hint="fix the script (modb.edit_scripts)")
    meta = json.loads(row["meta"])
    n_frames = edited["rotations"].shape[0]
    if n_frames != clip["rotations"].shape[0]:
        meta.pop("annotations", None)  # frame numbers: they stay with the version they describe
    record = {"edit_script": {"name": script, "commands": commands, "from_version": row["version"]}}
    translations = edited["translations"]
    skeleton_id, fps, mirrored = edited["skeleton"]["id"], edited["fps"], bool(row["mirrored"])
    rotations = edited["rotations"].astype(np.float32).tolist()
    translations = translations.astype(np.float32).tolist() if translations.shape[1] else None
    del row, clip, edited  # the float64 frames: only the lists the insert needs stay
    made = plpy.execute(add_version, [clip_id, skeleton_id, fps, n_frames, rotations, translations,
                                      json.dumps(record), json.dumps(meta)])[0]["version"]
    del rotations, translations
    plpy.execute(cut, [clip_id, mirrored])
    results.append((clip_id, made, n_frames, plpy.execute(count, [clip_id])[0]["n"]))
kernel.memory.release()  # a large edit's frames are garbage now: their memory goes back to the system
return results
$py$;
COMMENT ON FUNCTION modb._apply_edit_script(text, bigint[]) IS
    'Internal: what modb.apply_edit_script runs (PL/Python); call that one, whose errors read without Python''s exception names';
REVOKE EXECUTE ON FUNCTION modb._apply_edit_script(text, bigint[]) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._apply_edit_script(text, bigint[]) TO modb_loader;
CREATE FUNCTION modb.apply_edit_script(script text, clips bigint[])
RETURNS TABLE (clip_id bigint, version int, n_frames int, snippets bigint)
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._apply_edit_script(script, clips);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.apply_edit_script(text, bigint[]) IS
    'Applies the edit script to each clip''s current version: a new version per clip (load_params.edit_script records the script''s name, commands and the version it started from, so it can be replayed), cut into snippets as the clip was (mirrored too when it was); annotations stay with the old version when the frame count changes. Each clip once, however often named; a result past the caps on frames and bytes (docs/reference.md, Limits) is refused before any work; edits of one clip queue on its row. One transaction: a failing clip stores none';
REVOKE EXECUTE ON FUNCTION modb.apply_edit_script(text, bigint[]) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.apply_edit_script(text, bigint[]) TO modb_loader;
