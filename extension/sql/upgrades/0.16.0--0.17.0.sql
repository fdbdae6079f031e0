-- 0.17.0: hardening of the write surfaces (concurrent writes serialised, one frame-rate range and a cap
-- on the size of one result, bodies checked by type before work, messages a user can act on).
-- The PL/Python functions are re-created with the new kernel (build_sql.py).

-- Concurrent writes and caps (edit scripts, retargeting, snippet blocks).
-- Writers of a clip's versions queue on its row (40_clip_rules.sql).
CREATE OR REPLACE FUNCTION modb.clip_versions_before_insert()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    h jsonb;
    n_translated int;
BEGIN
    SELECT hierarchy INTO h FROM modb.skeletons WHERE id = NEW.skeleton_id;
    IF array_length(NEW.rotations, 2) IS DISTINCT FROM jsonb_array_length(h->'joints') THEN
        RAISE EXCEPTION 'rotations has % joints, skeleton % has %',
            array_length(NEW.rotations, 2), NEW.skeleton_id, jsonb_array_length(h->'joints')
            USING ERRCODE = 'check_violation',
                  HINT = 'rotations is real[n_frames][n_joints][4] with the joints in skeleton order';
    END IF;
    n_translated := coalesce(jsonb_array_length(h->'translated'), 0);
    IF coalesce(array_length(NEW.translations, 2), 0) <> n_translated THEN
        RAISE EXCEPTION 'translations has % joints, skeleton % has % joints with position channels',
            coalesce(array_length(NEW.translations, 2), 0), NEW.skeleton_id, n_translated
            USING ERRCODE = 'check_violation',
                  HINT = 'translations is real[n_frames][n_translated][3], NULL when no joint has position channels';
    END IF;
    -- Every writer of a clip's versions queues on its row (0.17.0), so the newest + 1 read below is
    -- still free when this insert commits; a writer that read the clip locked it already.
    PERFORM FROM modb.clips c WHERE c.id = NEW.clip_id FOR NO KEY UPDATE;
    IF NEW.version IS NULL THEN
        SELECT coalesce(max(version), 0) + 1 INTO NEW.version FROM modb.clip_versions WHERE clip_id = NEW.clip_id;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_before_insert() IS
    'Trigger: checks the frame arrays against the skeleton, locks the clip''s row (writers of its versions queue there) and numbers the version (newest + 1) when not given';

-- Writers of snippet blocks take the generation row before any block (71_snippet_blocks.sql).
DROP TRIGGER snippet_blocks_generation ON modb.snippet_blocks;
CREATE TRIGGER snippet_blocks_generation BEFORE INSERT OR UPDATE OR DELETE OR TRUNCATE ON modb.snippet_blocks
    FOR EACH STATEMENT EXECUTE FUNCTION modb.next_generation('snippet_blocks');

-- End of concurrent writes and caps.


-- Validation of stored documents (joint axes, joint maps, scripts, collection paths).
--@include 99_stored_document_checks.sql
-- Rows stored before these checks that fail them are repaired here, each with a WARNING (an update
-- hides NOTICEs), not left: the checks are triggers, which a restore's COPY runs too, so a row left as
-- it was would make the next dump fail to restore (and such rows already fail where they are read).
-- Each old value is kept in modb.repaired_rows. Joint axes go back to {} (the next retargeting derives
-- them again); collections named "." or ".." get a name; scripts that cannot run are deleted.
DO $$
DECLARE
    r record;
BEGIN
    FOR r IN SELECT id, joint_axes, modb.joint_axes_problem(hierarchy, joint_axes) AS problem FROM modb.skeletons
              WHERE modb.joint_axes_problem(hierarchy, joint_axes) IS NOT NULL ORDER BY id LOOP
        INSERT INTO modb.repaired_rows (table_name, row_key, old_value, problem, repaired_by)
        VALUES ('skeletons', r.id::text, jsonb_build_object('joint_axes', r.joint_axes), r.problem, '0.17.0');
        UPDATE modb.skeletons SET joint_axes = '{}' WHERE id = r.id;
        RAISE WARNING 'skeleton %: its joint_axes (%) are set to {}: the next retargeting derives them again; the old value is in modb.repaired_rows',
            r.id, r.problem;
    END LOOP;
    FOR r IN SELECT id, name, modb.collection_path(id) AS path FROM modb.collections
              WHERE name IN ('.', '..') OR btrim(name) = '' ORDER BY id LOOP
        INSERT INTO modb.repaired_rows (table_name, row_key, old_value, problem, repaired_by)
        VALUES ('collections', r.id::text, jsonb_build_object('name', r.name, 'path', r.path),
                '"." and ".." are not names', '0.17.0');
        UPDATE modb.collections SET name = 'renamed ' || r.id WHERE id = r.id;
        RAISE WARNING 'collection "%" is renamed "%": "." and ".." are not names', r.path, modb.collection_path(r.id);
    END LOOP;
    FOR r IN SELECT s.*, modb.edit_script_problems(s.commands) AS problems FROM modb.edit_scripts s
              WHERE cardinality(modb.edit_script_problems(s.commands)) > 0 ORDER BY s.name LOOP
        INSERT INTO modb.repaired_rows (table_name, row_key, old_value, problem, repaired_by)
        VALUES ('edit_scripts', r.name, to_jsonb(r) - 'problems', array_to_string(r.problems, '; '), '0.17.0');
        DELETE FROM modb.edit_scripts WHERE name = r.name;
        RAISE WARNING 'edit script "%" is deleted: it cannot run (%); its row is in modb.repaired_rows (commands %)',
            r.name, array_to_string(r.problems, '; '), r.commands;
    END LOOP;
END
$$;

-- End of validation.


-- Errors in words (15_errors_in_words.sql): the PL/Python functions a user calls become modb._NAME (re-created
-- below with the kernel), called through PL/pgSQL functions of the old names that raise their errors again
-- without Python's exception names. CREATE OR REPLACE keeps the old functions' comments and grants.
--@include 15_errors_in_words.sql
--@functions
REVOKE EXECUTE ON FUNCTION modb._build_snippets(text, bigint, float8, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._build_snippets(text, bigint, float8, float8, boolean) TO modb_loader;
CREATE OR REPLACE FUNCTION modb.build_snippets(collection text DEFAULT NULL, clip bigint DEFAULT NULL,
                                    window_seconds float8 DEFAULT 0.5, stride_seconds float8 DEFAULT 1.0 / 30,
                                    mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN modb._build_snippets(collection, clip, window_seconds, stride_seconds, mirrored);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;

REVOKE EXECUTE ON FUNCTION modb._retarget(bigint, bigint, text, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._retarget(bigint, bigint, text, float8, boolean) TO modb_loader;
CREATE OR REPLACE FUNCTION modb.retarget(clip bigint, skeleton bigint, collection text DEFAULT NULL,
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

REVOKE EXECUTE ON FUNCTION modb._apply_edit_script(text, bigint[]) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._apply_edit_script(text, bigint[]) TO modb_loader;
CREATE OR REPLACE FUNCTION modb.apply_edit_script(script text, clips bigint[])
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
COMMENT ON FUNCTION modb.retarget(bigint, bigint, text, float8, boolean) IS
    'Retargets the clip''s current motion onto the skeleton (its joint_axes: twist and swing aligned joint by joint, parents first; travel scaled by the legs'' length ratio; the feet as low as the source''s), resampled to fps (1 to 1000; default: the rate most of the skeleton''s clips have; a result past the caps on frames and bytes is refused before any work), and stores it as a clip of collection (default: "SOURCE_COLLECTION on skeleton N") named as the source, linked to it in meta and load_params.retargeted_from, cut into snippets (and mirrored ones when asked); a retargeting done before stores nothing. Returns the new clip''s id';
COMMENT ON FUNCTION modb.apply_edit_script(text, bigint[]) IS
    'Applies the edit script to each clip''s current version: a new version per clip (load_params.edit_script records the script''s name, commands and the version it started from, so it can be replayed), cut into snippets as the clip was (mirrored too when it was); annotations stay with the old version when the frame count changes. Each clip once, however often named; a result past the caps on frames and bytes (docs/reference.md, Limits) is refused before any work; edits of one clip queue on its row. One transaction: a failing clip stores none';
