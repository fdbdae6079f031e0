-- Checks used by table constraints. The frame checks are C (src/frame_checks.c): constant memory whatever
-- the clip's length.

CREATE OR REPLACE FUNCTION modb.unit_quaternions_ok(rotations real[], tolerance float8 DEFAULT 1e-5)
RETURNS boolean
LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_unit_quaternions_ok';
COMMENT ON FUNCTION modb.unit_quaternions_ok(real[], float8) IS
    'True when every (w,x,y,z) quaternion in the array (last dimension 4) has unit length within tolerance and w >= 0';

CREATE OR REPLACE FUNCTION modb.finite_ok(elements real[])
RETURNS boolean
LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_finite_ok';
COMMENT ON FUNCTION modb.finite_ok(real[]) IS 'True when the array holds no NULL, NaN or infinite element';

CREATE FUNCTION modb.skeleton_joint_names(hierarchy jsonb)
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY(SELECT j->>'name' FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n) ORDER BY n);
COMMENT ON FUNCTION modb.skeleton_joint_names(jsonb) IS 'Joint names of a skeleton hierarchy, in stored order';

CREATE FUNCTION modb.joint_map_ok(hierarchy jsonb, joint_map jsonb)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(joint_map) = 'object'
       AND NOT EXISTS (
           SELECT FROM jsonb_each(joint_map) AS m(standard, joint)
           WHERE m.standard <> ALL (ARRAY['pelvis', 'spine', 'chest', 'neck', 'head',
                   'left_hip', 'left_knee', 'left_ankle', 'left_toe', 'left_shoulder', 'left_elbow', 'left_wrist',
                   'right_hip', 'right_knee', 'right_ankle', 'right_toe', 'right_shoulder', 'right_elbow', 'right_wrist'])
              OR jsonb_typeof(m.joint) <> 'string'
              OR (m.joint #>> '{}') <> ALL (modb.skeleton_joint_names(hierarchy)));
END;
COMMENT ON FUNCTION modb.joint_map_ok(jsonb, jsonb) IS
    'True when joint_map maps standard joint names (pelvis, spine, chest, neck, head, left_/right_ hip, knee, ankle, toe, shoulder, elbow, wrist) onto joints of the hierarchy';

CREATE FUNCTION modb.mirror_pairs_ok(hierarchy jsonb, mirror_pairs jsonb)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(mirror_pairs) = 'array'
       AND NOT EXISTS (
           SELECT FROM jsonb_array_elements(mirror_pairs) AS p(pair)
           WHERE jsonb_typeof(p.pair) <> 'array' OR jsonb_array_length(p.pair) <> 2
              OR (p.pair->>0) = (p.pair->>1)
              OR (p.pair->>0) <> ALL (modb.skeleton_joint_names(hierarchy))
              OR (p.pair->>1) <> ALL (modb.skeleton_joint_names(hierarchy)))
       AND (SELECT count(*) = count(DISTINCT name)
              FROM jsonb_array_elements(mirror_pairs) AS p(pair),
                   LATERAL jsonb_array_elements_text(CASE WHEN jsonb_typeof(p.pair) = 'array' THEN p.pair ELSE '[]' END) AS n(name));
END;
COMMENT ON FUNCTION modb.mirror_pairs_ok(jsonb, jsonb) IS
    'True when mirror_pairs is a list of [left, right] joint-name pairs of the hierarchy, each joint in at most one pair';

CREATE FUNCTION modb.annotations_ok(meta jsonb, n_frames int)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(meta) = 'object'
       AND (NOT meta ? 'annotations' OR (
            jsonb_typeof(meta->'annotations') = 'array'
        AND NOT EXISTS (
            SELECT FROM jsonb_array_elements(meta->'annotations') AS a(seg)
            WHERE jsonb_typeof(a.seg) <> 'object'
               OR jsonb_typeof(a.seg->'name') IS DISTINCT FROM 'string'
               OR jsonb_typeof(a.seg->'start') IS DISTINCT FROM 'number'
               OR jsonb_typeof(a.seg->'end') IS DISTINCT FROM 'number'
               OR NOT ((a.seg->>'start')::numeric BETWEEN 0 AND (a.seg->>'end')::numeric)
               OR (a.seg->>'end')::numeric >= n_frames
               OR (a.seg ? 'auto' AND jsonb_typeof(a.seg->'auto') <> 'boolean')
               OR (a.seg ? 'keyframes' AND (jsonb_typeof(a.seg->'keyframes') <> 'array' OR EXISTS (
                   SELECT FROM jsonb_array_elements(a.seg->'keyframes') AS k(frame)
                    WHERE jsonb_typeof(k.frame) <> 'number'
                       OR NOT (k.frame::text::numeric BETWEEN (a.seg->>'start')::numeric
                                                          AND (a.seg->>'end')::numeric)))))));
END;
COMMENT ON FUNCTION modb.annotations_ok(jsonb, int) IS
    'True when meta is an object whose optional "annotations" list holds {name, start, end} segments with 0 <= start <= end < n_frames (frames, 0-based), each with optional "keyframes" (frames within it) and "auto" (true: found by modb.annotate_steps)';

CREATE FUNCTION modb.skeleton_identity(hierarchy jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- A joint whose three position channels replace its offset in every frame (Bandai stores the first
    -- frame's travel in the Hips offset) has an offset that changes no pose: leave it out, so one
    -- skeleton serves every file of a capture session.
    SELECT encode(sha256(convert_to((
        (hierarchy - 'rest_positions') || jsonb_build_object('joints', (
            SELECT jsonb_agg(CASE WHEN j->'channels' @> '["Xposition", "Yposition", "Zposition"]'
                                    OR j->'channels' @> '["TX", "TY", "TZ"]'
                                  THEN j - 'offset' ELSE j END ORDER BY n)
              FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n))))::text, 'UTF8')), 'hex');
END;
COMMENT ON FUNCTION modb.skeleton_identity(jsonb) IS
    'sha256 identifying a skeleton: its hierarchy without rest positions and without the offsets of joints whose position channels replace them';
