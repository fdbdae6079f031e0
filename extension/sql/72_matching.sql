-- How two terminators are compared: the quaternion-angle operator, configuration-level distances,
-- match profiles with per-session knobs, and the per-dimension search box.

CREATE FUNCTION modb.standard_joints()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN {{STANDARD_JOINTS}};  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.standard_joints() IS
    'The standard joints in the order terminator arrays use (index 0 = pelvis); a joint map maps them onto a skeleton';

CREATE FUNCTION modb.feature_names()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN {{FEATURES}};  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.feature_names() IS 'The 49 dimensions of the indexed feature cube, in order (metres, m/s, and rotation-matrix entries)';

CREATE FUNCTION modb.quat_angle(aw float8, ax float8, ay float8, az float8, bw float8, bx float8, by float8, bz float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE  -- not STRICT: least() is not, and a STRICT
                                                           -- function with it in its body is never inlined
-- For unit quaternions |a-b|^2 + |a+b|^2 = 4 and a.b >= 0 exactly when |a-b| <= |a+b|, so taking the
-- smaller as the chord treats q and -q as one rotation; 4*atan2 of the chords is accurate near 0 and pi.
RETURN 4 * atan2(least(sqrt((aw - bw) ^ 2 + (ax - bx) ^ 2 + (ay - by) ^ 2 + (az - bz) ^ 2),
                       sqrt((aw + bw) ^ 2 + (ax + bx) ^ 2 + (ay + by) ^ 2 + (az + bz) ^ 2)),
                 greatest(sqrt((aw - bw) ^ 2 + (ax - bx) ^ 2 + (ay - by) ^ 2 + (az - bz) ^ 2),
                          sqrt((aw + bw) ^ 2 + (ax + bx) ^ 2 + (ay + by) ^ 2 + (az + bz) ^ 2)));
COMMENT ON FUNCTION modb.quat_angle(float8, float8, float8, float8, float8, float8, float8, float8) IS
    'Rotation angle (radians, 0..pi) between unit quaternions (aw, ax, ay, az) and (bw, bx, by, bz)';

CREATE FUNCTION modb.quat_angle(a float8[], b float8[])
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
RETURN modb.quat_angle(a[1], a[2], a[3], a[4], b[1], b[2], b[3], b[4]);
COMMENT ON FUNCTION modb.quat_angle(float8[], float8[]) IS
    'Rotation angle (radians, 0..pi) between two unit quaternions (w, x, y, z); q and -q are the same rotation';

CREATE OPERATOR modb.<%> (
    LEFTARG = float8[], RIGHTARG = float8[], FUNCTION = modb.quat_angle, COMMUTATOR = OPERATOR(modb.<%>)
);
COMMENT ON OPERATOR modb.<%> (float8[], float8[]) IS 'Rotation angle (radians) between two unit quaternions';

CREATE FUNCTION modb.max_joint_angle(a real[], b real[], joints int[])
RETURNS float8
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT max(a[4 * j + 1:4 * j + 4]::float8[] OPERATOR(modb.<%>) b[4 * j + 1:4 * j + 4]::float8[]) FROM unnest(joints) AS j;
END;
COMMENT ON FUNCTION modb.max_joint_angle(real[], real[], int[]) IS
    'Largest rotation angle between two configurations (flat arrays of (w,x,y,z) per joint) over the given joint indices (0-based)';

CREATE FUNCTION modb.weighted_joint_angle(a real[], b real[], joints int[], weights float8[])
RETURNS float8
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT sum(w * (a[4 * j + 1:4 * j + 4]::float8[] OPERATOR(modb.<%>) b[4 * j + 1:4 * j + 4]::float8[]))
      FROM unnest(joints, weights) AS t(j, w);
END;
COMMENT ON FUNCTION modb.weighted_joint_angle(real[], real[], int[], float8[]) IS
    'Weighted sum of rotation angles between two configurations over a joint subset (0-based indices, one weight each)';

CREATE TABLE modb.match_profiles (
    name     text PRIMARY KEY,
    settings jsonb NOT NULL CHECK (jsonb_typeof(settings) = 'object'),
    comment  text,
    shipped  boolean NOT NULL DEFAULT false
);
COMMENT ON TABLE modb.match_profiles IS
    'Continuity thresholds for select_next_snippet, by name; any setting can be overridden per session with SET modb.<knob>';

-- The shipped profiles: 73_profiles.sql (also run by upgrades, so they follow the release).

GRANT SELECT ON modb.match_profiles TO modb_reader;
GRANT INSERT, UPDATE, DELETE ON modb.match_profiles TO modb_loader;

-- The shipped profiles come with every install (and upgrade); pg_dump keeps the ones users add.
SELECT pg_catalog.pg_extension_config_dump('modb.match_profiles', 'WHERE NOT shipped');
COMMENT ON COLUMN modb.match_profiles.shipped IS
    'Installed with the extension (and replaced by its upgrades): add your own profile rather than editing these';

CREATE TYPE modb.match_plan AS (
    joints                     int[],
    position_threshold         float8[],
    angle_threshold            float8[],
    velocity_threshold         float8[],
    angular_velocity_threshold float8[],
    norm                       text,
    velocity_terms             boolean,
    heading_weight             float8,
    box_half_width             float8[],
    continuity_weight          float8,
    lookahead_distance         float8,
    graph_id                   bigint,
    graph_lookahead            boolean,
    graph_cost_to_go           boolean
);
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, and whether it ranks by the graph''s cost-to-go';

CREATE FUNCTION modb.session_settings()
RETURNS text[]
LANGUAGE c STABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_session_settings';
COMMENT ON FUNCTION modb.session_settings() IS
    'Names of this session''s modb.* settings that have a value (pg_settings does not list them: they are placeholders)';

CREATE FUNCTION modb._thresholds(spec jsonb, joints text[], included text[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
BEGIN ATOMIC
    SELECT array_agg(CASE WHEN j <> ALL (included) THEN 'Infinity'::float8
                          WHEN jsonb_typeof(spec) = 'number' THEN spec::text::float8
                          ELSE coalesce((spec->>j)::float8, (spec->>'default')::float8) END ORDER BY n)
      FROM unnest(joints) WITH ORDINALITY AS t(j, n);
END;
COMMENT ON FUNCTION modb._thresholds(jsonb, text[], text[]) IS
    'Internal: a threshold per joint from a number or {"default": x, "<joint>": y}; Infinity for joints not included';

-- modb.continuity_ratio: 72_matching_continuity.sql

CREATE FUNCTION modb.match_box(features cube, plan modb.match_plan, scale float8)
RETURNS cube
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- + 1e-4: terminators store float4 and features float8; the margin keeps every candidate that passes
    -- the exact check inside the box, so a row's level depends on its ratio alone.
    SELECT cube(array_agg(cube_ll_coord(features, i) - scale * (plan).box_half_width[i] - 1e-4 ORDER BY i),
                array_agg(cube_ll_coord(features, i) + scale * (plan).box_half_width[i] + 1e-4 ORDER BY i))
      FROM generate_series(1, cube_dim(features)) AS i;
END;
COMMENT ON FUNCTION modb.match_box(cube, modb.match_plan, float8) IS
    'The per-dimension search box around a feature point: each feature +- scale x its joint''s threshold';

CREATE FUNCTION modb.target_cost(net_translation float8[], net_heading float8, target float8[], heading_weight float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
RETURN CASE WHEN array_length(target, 1) = 3
            THEN sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[2] - target[2]) ^ 2 + (net_translation[3] - target[3]) ^ 2)
            ELSE sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[3] - target[2]) ^ 2) END
       + heading_weight * abs(atan2(sin(net_heading - atan2(target[1], target[array_length(target, 1)])),
                                    cos(net_heading - atan2(target[1], target[array_length(target, 1)]))));
COMMENT ON FUNCTION modb.target_cost(float8[], float8, float8[], float8) IS
    'Distance (m) from a snippet''s net translation to the target {x, z} or {x, y, z}, plus heading_weight x |heading change - direction of the target| (radians)';

CREATE FUNCTION modb.collection_subtree(path text)
RETURNS bigint[]
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    WITH RECURSIVE down(id, depth) AS (
        SELECT id, 0 FROM modb.collections WHERE id = modb.find_collection(path)
        UNION ALL
        SELECT c.id, down.depth + 1 FROM modb.collections c JOIN down ON c.parent_id = down.id WHERE down.depth < 1000
    )
    SELECT coalesce(array_agg(id), '{}') FROM down;
END;
COMMENT ON FUNCTION modb.collection_subtree(text) IS 'Ids of the collection at path "a/b" and of every collection below it';

CREATE FUNCTION modb.check_request(prev_snippet bigint, target float8[], k int, collection text)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    IF target IS NULL OR array_length(target, 1) NOT IN (2, 3) OR array_ndims(target) <> 1
       OR EXISTS (SELECT FROM unnest(target) v WHERE v IS NULL OR v = 'NaN' OR v IN ('Infinity', '-Infinity')) THEN
        RAISE EXCEPTION 'target must be {x, z} or {x, y, z} in metres, got %', coalesce(target::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF k IS NULL OR k < 1 THEN
        RAISE EXCEPTION 'k must be at least 1, got %', coalesce(k::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF prev_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = prev_snippet) THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'prev_snippet is a modb.snippets id, or NULL to start';
    END IF;
    IF collection IS NOT NULL AND modb.find_collection(collection) IS NULL THEN
        RAISE EXCEPTION 'no collection "%"', collection USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_request(bigint, float8[], int, text) IS
    'Raises a clear error for a select_next_snippet request that cannot be answered (bad target or k, unknown snippet or collection)';
