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
