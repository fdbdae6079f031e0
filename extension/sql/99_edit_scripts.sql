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

CREATE OR REPLACE FUNCTION modb.apply_edit_script(script text, clips bigint[])
RETURNS TABLE (clip_id bigint, version int, n_frames int, snippets bigint)
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel
import json
import numpy as np

R, E = kernel.retarget, kernel.edits
found = plpy.execute(plpy.prepare("SELECT commands FROM modb.edit_scripts WHERE name = $1", ["text"]), [script])
if not found:
    plpy.error(f'no edit script "{script}"', hint="SELECT name FROM modb.edit_scripts lists them")
commands = json.loads(found[0]["commands"])
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
    sk = R.skeleton(json.loads(row["hierarchy"]), json.loads(row["joint_map"]), json.loads(row["joint_axes"]),
                    json.loads(row["mirror_pairs"]))
    sk["id"] = skeleton_id
    return sk

def fetch(clip_id):
    if not isinstance(clip_id, int):
        return None
    rows = plpy.execute(read_clip, [clip_id])
    if not rows:
        return None
    r, t = frames(rows[0]["rotations"], rows[0]["translations"])
    return {"skeleton": skeleton_of(rows[0], rows[0]["skeleton_id"]), "fps": rows[0]["fps"], "rotations": r,
            "translations": t}

def fetch_skeleton(skeleton_id):
    if not isinstance(skeleton_id, int):
        return None
    rows = plpy.execute(read_skeleton, [skeleton_id])
    if not rows:
        return None
    reference = None if rows[0]["rotations"] is None else frames(rows[0]["rotations"], rows[0]["translations"])
    return skeleton_of(rows[0], skeleton_id), reference

results = []  # returned whole: an error raised inside a generator would lose its message
for clip_id in clips or []:
    rows = plpy.execute(read_clip, [clip_id])
    if not rows:
        plpy.error(f"no clip {clip_id} with a version", hint="modb.current_clips lists the stored clips")
    row = rows[0]
    clip = fetch(clip_id)
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
    made = plpy.execute(add_version, [
        clip_id, edited["skeleton"]["id"], edited["fps"], n_frames, edited["rotations"].astype(np.float32).tolist(),
        translations.astype(np.float32).tolist() if translations.shape[1] else None,
        json.dumps(record), json.dumps(meta)])[0]["version"]
    plpy.execute(cut, [clip_id, bool(row["mirrored"])])
    results.append((clip_id, made, n_frames, plpy.execute(count, [clip_id])[0]["n"]))
return results
$py$;
COMMENT ON FUNCTION modb.apply_edit_script(text, bigint[]) IS
    'Applies the edit script to each clip''s current version: a new version per clip (load_params.edit_script records the script''s name, commands and the version it started from, so it can be replayed), cut into snippets as the clip was (mirrored too when it was); annotations stay with the old version when the frame count changes. One transaction: a failing clip stores none';
REVOKE EXECUTE ON FUNCTION modb.apply_edit_script(text, bigint[]) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.apply_edit_script(text, bigint[]) TO modb_loader;
