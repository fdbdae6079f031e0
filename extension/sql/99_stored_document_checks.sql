-- Checks of the documents users store (0.17.0): joint axes, joint maps, edit scripts and collection
-- names, made here so every writer (SQL, the REST interface, the command line) meets the same one, and
-- in words: a trigger raises a message naming the object and what to do, where a CHECK constraint could
-- only name itself. A trigger checks what a statement writes, never the rows already stored, so an
-- update of the extension cannot fail on them (its upgrade script repairs those, saying so).

CREATE FUNCTION modb.joint_axes_problem(hierarchy jsonb, joint_axes jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT CASE
        WHEN jsonb_typeof(joint_axes) <> 'object' THEN 'joint_axes must be an object'
        WHEN joint_axes ? 'joints' AND jsonb_typeof(joint_axes->'joints') <> 'object'
            THEN '"joints" must be an object {standard name: {"joint", "twist", "swing"}}'
        ELSE coalesce(
            (SELECT format('joints.%s: %s', a.standard, CASE
                        WHEN jsonb_typeof(a.axes) <> 'object' THEN 'must be {"joint", "twist", "swing"}'
                        WHEN jsonb_typeof(a.axes->'joint') IS DISTINCT FROM 'string'
                          OR (a.axes->>'joint') <> ALL (modb.skeleton_joint_names(hierarchy))
                            THEN '"joint" must name a joint of the skeleton'
                        ELSE '"twist" and "swing" must be lists of three numbers' END)
               FROM jsonb_each(CASE WHEN joint_axes ? 'joints' THEN joint_axes->'joints' ELSE '{}' END)
                    AS a(standard, axes)
              WHERE jsonb_typeof(a.axes) <> 'object'
                 OR jsonb_typeof(a.axes->'joint') IS DISTINCT FROM 'string'
                 OR (a.axes->>'joint') <> ALL (modb.skeleton_joint_names(hierarchy))
                 OR EXISTS (SELECT FROM unnest(ARRAY['twist', 'swing']) AS k(key)
                             WHERE jsonb_typeof(a.axes->k.key) IS DISTINCT FROM 'array'
                                OR jsonb_array_length(a.axes->k.key) <> 3
                                OR EXISTS (SELECT FROM jsonb_array_elements(a.axes->k.key) AS e(v)
                                            WHERE jsonb_typeof(e.v) <> 'number'))
              ORDER BY a.standard LIMIT 1),
            CASE WHEN jsonb_typeof(joint_axes->'pose') IS NOT DISTINCT FROM 'null' OR NOT joint_axes ? 'pose'
                     THEN NULL
                 WHEN jsonb_typeof(joint_axes->'pose') <> 'array'
                   OR jsonb_array_length(joint_axes->'pose') <> jsonb_array_length(hierarchy->'joints')
                   OR EXISTS (SELECT FROM jsonb_array_elements(joint_axes->'pose') AS p(q)
                               WHERE jsonb_typeof(p.q) <> 'array' OR jsonb_array_length(p.q) <> 4
                                  OR EXISTS (SELECT FROM jsonb_array_elements(p.q) AS e(v)
                                              WHERE jsonb_typeof(e.v) <> 'number'))
                     THEN format('"pose" must be null or a list of %s quaternions [w, x, y, z] (numbers), '
                                 'one per joint', jsonb_array_length(hierarchy->'joints'))
            END)
    END;
END;
COMMENT ON FUNCTION modb.joint_axes_problem(jsonb, jsonb) IS
    'Why joint_axes is not {} or {"joints": {standard: {"joint" (of the hierarchy), "twist": [3 numbers], "swing": [3 numbers]}}, "pose": null or a [w,x,y,z] of numbers per joint}; NULL when it is';

CREATE FUNCTION modb.skeletons_check_documents()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    problem text;
BEGIN
    IF TG_OP = 'UPDATE' AND NEW.joint_map = '{}' AND OLD.joint_map <> '{}' THEN
        RAISE EXCEPTION 'the joint map of skeleton % cannot be emptied: its clips are cut into snippets through it', OLD.id
            USING ERRCODE = 'check_violation',
                  HINT = 'map the standard joints (pelvis, spine, ..., right_wrist) onto its joints; '
                         '`modb list --skeletons` shows the map it has';
    END IF;
    IF NOT modb.joint_map_ok(NEW.hierarchy, NEW.joint_map) THEN
        RAISE EXCEPTION 'the joint map of skeleton % is not {standard name: joint name}', coalesce(NEW.id::text, '(new)')
            USING ERRCODE = 'check_violation',
                  HINT = 'keys: pelvis, spine, chest, neck, head, left_/right_ hip, knee, ankle, toe, shoulder, '
                         'elbow, wrist; values: names of the skeleton''s joints';
    END IF;
    IF TG_OP = 'INSERT' OR NEW.joint_axes IS DISTINCT FROM OLD.joint_axes THEN
        problem := modb.joint_axes_problem(NEW.hierarchy, NEW.joint_axes);
        IF problem IS NOT NULL THEN
            RAISE EXCEPTION 'the joint_axes of skeleton %: %', coalesce(NEW.id::text, '(new)'), problem
                USING ERRCODE = 'check_violation',
                      HINT = 'store {} to have the next retargeting derive them';
        END IF;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.skeletons_check_documents() IS
    'Trigger: a skeleton''s joint map is {standard: joint} and is never emptied once set, its joint_axes hold numbers (modb.joint_axes_problem); each refusal says why';
CREATE TRIGGER skeletons_check_documents BEFORE INSERT OR UPDATE OF joint_map, joint_axes ON modb.skeletons
    FOR EACH ROW EXECUTE FUNCTION modb.skeletons_check_documents();

CREATE OR REPLACE FUNCTION modb.edit_script_problems(commands jsonb)
RETURNS text[]
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
#@modb_kernel edits
import json
return kernel.edits.script_errors(json.loads(commands))
$py$;
COMMENT ON FUNCTION modb.edit_script_problems(jsonb) IS
    'Why a list of edit commands cannot run whatever the clip (not a non-empty list of known commands with parameters of the right types and ranges): one message each, empty when it can';

CREATE FUNCTION modb.edit_scripts_check_commands()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    problems text[] := modb.edit_script_problems(NEW.commands);
BEGIN
    IF cardinality(problems) > 0 THEN
        RAISE EXCEPTION 'edit script "%": %', NEW.name, array_to_string(problems, '; ')
            USING ERRCODE = 'check_violation',
                  HINT = 'a script is a list of {"op": mirror | trim (start, end) | smooth (seconds) | resample (fps) | '
                         'time_stretch (factor) | copy_joints (clip, joints, start, end, source_start, blend) | '
                         'retarget (skeleton)}';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.edit_scripts_check_commands() IS
    'Trigger: an edit script is stored only as a list of known commands with parameters of the right types (modb.edit_script_problems)';
CREATE TRIGGER edit_scripts_check_commands BEFORE INSERT OR UPDATE OF commands ON modb.edit_scripts
    FOR EACH ROW EXECUTE FUNCTION modb.edit_scripts_check_commands();

CREATE FUNCTION modb.collections_check_name()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF NEW.name IN ('.', '..') OR btrim(NEW.name) = '' THEN
        RAISE EXCEPTION 'a collection cannot be named "%": the parts of a collection path are names', NEW.name
            USING ERRCODE = 'check_violation', HINT = 'give a name that is not empty, "." or ".."';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.collections_check_name() IS
    'Trigger: a collection''s name (a part of its path) is a name: not empty, "." or ".."';
CREATE TRIGGER collections_check_name BEFORE INSERT OR UPDATE OF name ON modb.collections
    FOR EACH ROW EXECUTE FUNCTION modb.collections_check_name();

-- What an update of the extension repaired, as it was: a row stored before a check that refuses it is
-- changed so a dump of the database restores (the checks run on a restore's COPY too), and its old
-- value is kept here, so nothing a user stored is lost.
CREATE TABLE modb.repaired_rows (
    id          bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    table_name  text NOT NULL,
    row_key     text NOT NULL,
    old_value   jsonb NOT NULL,
    problem     text NOT NULL,
    repaired_by text NOT NULL,
    repaired_at timestamptz NOT NULL DEFAULT now()
);
COMMENT ON TABLE modb.repaired_rows IS
    'Rows an update of the extension repaired because a newer check refuses them: the table, the row''s key, its old value, the problem and the version that repaired it';
SELECT pg_catalog.pg_extension_config_dump('modb.repaired_rows', '');
SELECT pg_catalog.pg_extension_config_dump('modb.repaired_rows_id_seq', '');
GRANT SELECT ON modb.repaired_rows TO modb_loader;
