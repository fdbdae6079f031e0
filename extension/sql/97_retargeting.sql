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
-- to its source, cut into snippets (modb_kernel/retarget_clip.py, which a job worker runs too). CREATE OR
-- REPLACE: upgrades include this file when it changes.
CREATE OR REPLACE FUNCTION modb._retarget(clip bigint, skeleton bigint, collection text DEFAULT NULL,
                                         fps float8 DEFAULT NULL, mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel database retarget_clip
D = kernel.database
try:
    return kernel.retarget_clip.retarget_clip(D.Server(plpy), clip, skeleton, collection, fps, mirrored)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
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
