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
    'Edit scripts: [{"op": "mirror" | "trim" (start, end) | "smooth" (seconds) | "resample" (fps) | "time_stretch" (factor) | "copy_joints" (clip, joints, start, end, source_start, blend) | "retarget" (skeleton) | "ik" (joint, time, offset, orientation, chain, before, after) | "rotate" (joint, time, rotation, before, after)}, ...], applied in order by modb.apply_edit_script';
SELECT pg_catalog.pg_extension_config_dump('modb.edit_scripts', '');
GRANT SELECT ON modb.edit_scripts TO modb_reader;
GRANT INSERT (name, commands, comment), UPDATE (commands, comment), DELETE ON modb.edit_scripts TO modb_loader;

CREATE OR REPLACE FUNCTION modb._apply_edit_script(script text, clips bigint[])
RETURNS TABLE (clip_id bigint, version int, n_frames int, snippets bigint)
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel database edit_clips
D = kernel.database
try:  # returned whole: an error raised inside a generator would lose its message
    return kernel.edit_clips.apply_script(D.Server(plpy), script, clips)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
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
