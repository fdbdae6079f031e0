\echo Use "ALTER EXTENSION modb UPDATE TO '0.2.0'" to load this file. \quit

-- 0.1.0 -> 0.2.0: snippets, terminators, matching and select_next_snippet.
-- 70_snippets.sql
-- Snippets (~0.5 s windows of real capture), the terminators at their ends, and where they came from.
-- The frames themselves stay in modb.clip_versions: a snippet is a window onto them, never a copy.

CREATE FUNCTION modb.skeleton_pose_key(hierarchy jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- End Sites move no joint: snippets of skeletons that differ only there may follow each other.
    SELECT modb.skeleton_identity(jsonb_set(hierarchy, '{joints}', (
        SELECT jsonb_agg(j - 'end_site' ORDER BY n)
          FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n))));
END;
COMMENT ON FUNCTION modb.skeleton_pose_key(jsonb) IS
    'Identity of the poses a skeleton can take (skeleton_identity without End Sites): snippets chain only within one';

CREATE TABLE modb.snippet_sources (
    clip_id       bigint NOT NULL,
    version       int NOT NULL,
    mirrored      boolean NOT NULL,
    window_frames int NOT NULL CHECK (window_frames > 1),
    stride_frames int NOT NULL CHECK (stride_frames > 0),
    built_at      timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (clip_id, version, mirrored),
    FOREIGN KEY (clip_id, version) REFERENCES modb.clip_versions (clip_id, version) ON DELETE CASCADE
);
COMMENT ON TABLE modb.snippet_sources IS
    'Clip versions (as captured or mirrored) cut into snippets, with the window and stride used (frames)';

CREATE TABLE modb.terminators (
    id                 bigserial PRIMARY KEY,
    clip_id            bigint NOT NULL,
    version            int NOT NULL,
    mirrored           boolean NOT NULL,
    frame              int NOT NULL CHECK (frame >= 0),
    heading            float8 NOT NULL,
    pelvis_height      real NOT NULL,
    positions          real[] NOT NULL CHECK (array_length(positions, 1) = 57),
    rotations          real[] NOT NULL CHECK (array_length(rotations, 1) = 76),
    velocities         real[] NOT NULL CHECK (array_length(velocities, 1) = 57),
    angular_velocities real[] NOT NULL CHECK (array_length(angular_velocities, 1) = 57),
    configuration      real[] NOT NULL,
    features           cube NOT NULL CHECK (cube_dim(features) = 25),
    UNIQUE (clip_id, version, mirrored, frame),
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE
);
COMMENT ON TABLE modb.terminators IS
    'MotionTerminator: the configuration at a frame that begins or ends a snippet, in that frame''s local heading frame';
COMMENT ON COLUMN modb.terminators.heading IS 'World heading (radians about +Y, 0 = facing +Z) of the frame, smoothed over 0.5 s';
COMMENT ON COLUMN modb.terminators.positions IS
    'Standard joints (modb.standard_joints() order) x (x, y, z): metres, local heading frame, origin at the pelvis on the ground';
COMMENT ON COLUMN modb.terminators.rotations IS
    'Standard joints x (w, x, y, z): the pelvis in the heading frame, every other joint relative to its parent';
COMMENT ON COLUMN modb.terminators.velocities IS 'Standard joints x (x, y, z) m/s, local heading frame';
COMMENT ON COLUMN modb.terminators.angular_velocities IS
    'Standard joints x (x, y, z) rad/s: the pelvis in the heading frame, other joints in their own frame';
COMMENT ON COLUMN modb.terminators.configuration IS
    'real[n_joints][4]: every joint''s unit quaternion (skeleton order); the pelvis in the heading frame';
COMMENT ON COLUMN modb.terminators.features IS
    'The indexed feature vector, physical units: modb.feature_names() lists its 25 dimensions';

CREATE TABLE modb.snippets (
    id               bigserial PRIMARY KEY,
    clip_id          bigint NOT NULL,
    version          int NOT NULL,
    mirrored         boolean NOT NULL,
    first_frame      int NOT NULL CHECK (first_frame >= 0),
    n_frames         int NOT NULL CHECK (n_frames > 1),
    collection_id    bigint NOT NULL,
    pose_key         text NOT NULL,
    fps              float8 NOT NULL,
    begin_terminator bigint NOT NULL REFERENCES modb.terminators (id) ON DELETE CASCADE,
    end_terminator   bigint NOT NULL REFERENCES modb.terminators (id) ON DELETE CASCADE,
    begin_features   cube NOT NULL,
    net_translation  float8[] NOT NULL CHECK (array_length(net_translation, 1) = 3),
    net_heading      float8 NOT NULL,
    net_rotation     float8[] NOT NULL CHECK (array_length(net_rotation, 1) = 4),
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE
);
COMMENT ON TABLE modb.snippets IS
    'SnippetDescriptor: frames first_frame .. first_frame + n_frames - 1 of a clip version; played after another snippet, its first frame stands in for that one''s last';
COMMENT ON COLUMN modb.snippets.begin_features IS 'Copy of the begin terminator''s features, so the GiST index serves the selection alone';
COMMENT ON COLUMN modb.snippets.net_translation IS 'Pelvis travel (x left, y up, z forward; metres) in the heading frame of the first frame';
COMMENT ON COLUMN modb.snippets.net_heading IS 'Heading change over the snippet (radians, counter-clockwise seen from above)';
COMMENT ON COLUMN modb.snippets.net_rotation IS 'The heading change as a unit quaternion (w, x, y, z) about +Y';

CREATE INDEX snippets_begin_features_idx ON modb.snippets USING gist (begin_features);
CREATE INDEX snippets_clip_idx ON modb.snippets (clip_id, version, mirrored, first_frame);
CREATE INDEX snippets_pose_key_idx ON modb.snippets (pose_key, fps);

SELECT pg_catalog.pg_extension_config_dump('modb.snippet_sources', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets_id_seq', '');

GRANT SELECT ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_reader;
GRANT INSERT, DELETE ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_loader;
GRANT USAGE ON modb.terminators_id_seq, modb.snippets_id_seq TO modb_loader;

-- 72_matching.sql
-- How two terminators are compared: the quaternion-angle operator, configuration-level distances,
-- match profiles with per-session knobs, and the per-dimension search box.

CREATE FUNCTION modb.standard_joints()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN ARRAY['pelvis', 'spine', 'chest', 'neck', 'head', 'left_hip', 'left_knee', 'left_ankle', 'left_toe', 'left_shoulder', 'left_elbow', 'left_wrist', 'right_hip', 'right_knee', 'right_ankle', 'right_toe', 'right_shoulder', 'right_elbow', 'right_wrist'];  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.standard_joints() IS
    'The standard joints in the order terminator arrays use (index 0 = pelvis); a joint map maps them onto a skeleton';

CREATE FUNCTION modb.feature_names()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN ARRAY['pelvis.y', 'head.x', 'head.y', 'head.z', 'left_wrist.x', 'left_wrist.y', 'left_wrist.z', 'right_wrist.x', 'right_wrist.y', 'right_wrist.z', 'left_ankle.x', 'left_ankle.y', 'left_ankle.z', 'right_ankle.x', 'right_ankle.y', 'right_ankle.z', 'pelvis.vx', 'pelvis.vy', 'pelvis.vz', 'left_ankle.vx', 'left_ankle.vy', 'left_ankle.vz', 'right_ankle.vx', 'right_ankle.vy', 'right_ankle.vz'];  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.feature_names() IS 'The 25 dimensions of the indexed feature cube, in order (metres, m/s)';

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

INSERT INTO modb.match_profiles (name, settings, comment, shipped) VALUES
('default', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
              "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
              "right_shoulder", "right_elbow", "right_wrist"],
              "norm": "l2", "position_threshold": {"default": 0.12, "left_wrist": 0.2, "right_wrist": 0.2,
              "left_elbow": 0.16, "right_elbow": 0.16},
              "angle_threshold": {"default": 0.5, "pelvis": 0.3}, "velocity_threshold": {"default": 0.6, "left_wrist": 1.0,
              "right_wrist": 1.0, "left_elbow": 0.8, "right_elbow": 0.8},
              "angular_velocity_threshold": {"default": 4.0}, "velocity_terms": true, "heading_weight": 0.0}',
 'Whole body: feet, hands and head within centimetres, joints within about 30 degrees, velocities matched', true),
('strict', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
             "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
             "right_shoulder", "right_elbow", "right_wrist"],
             "norm": "l2", "position_threshold": {"default": 0.06}, "angle_threshold": {"default": 0.25},
             "velocity_threshold": {"default": 0.3}, "angular_velocity_threshold": {"default": 2.0},
             "velocity_terms": true, "heading_weight": 0.0}',
 'Half the default thresholds: smoother seams, more relaxation', true),
('locomotion', '{"joints": ["pelvis", "left_hip", "left_knee", "left_ankle", "left_toe", "right_hip", "right_knee",
                 "right_ankle", "right_toe"],
                 "norm": "l1", "position_threshold": {"default": 0.15}, "angle_threshold": {"default": 0.5},
                 "velocity_threshold": {"default": 0.7}, "angular_velocity_threshold": {"default": 5.0},
                 "velocity_terms": true, "heading_weight": 0.3}',
 'Lower body only, L1 positions, and a heading term: for walking to goals', true);

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
    box_half_width             float8[]
);
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), and the half-widths of the search box per feature';

CREATE FUNCTION modb.match_knobs()
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY['joints', 'norm', 'position_threshold', 'angle_threshold', 'velocity_threshold',
             'angular_velocity_threshold', 'velocity_terms', 'heading_weight'];
COMMENT ON FUNCTION modb.match_knobs() IS 'Settings a session may override with SET modb.<knob> = ...';

CREATE FUNCTION modb.session_settings()
RETURNS text[]
LANGUAGE c STABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_session_settings';
COMMENT ON FUNCTION modb.session_settings() IS
    'Names of this session''s modb.* settings that have a value (pg_settings does not list them: they are placeholders)';

CREATE FUNCTION modb.match_plan(profile text)
RETURNS modb.match_plan
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    settings jsonb;
    knob text;
    value text;
    unknown text;
    plan modb.match_plan;
    names text[] := modb.standard_joints();
    features text[] := modb.feature_names();
    joint_names text[];
    position_by_joint float8[];
    velocity_by_joint float8[];
    included boolean[];
    feature text;
    joint text;
    s int;
BEGIN
    SELECT p.settings INTO settings FROM modb.match_profiles p WHERE p.name = coalesce(profile, 'default');
    IF NOT FOUND THEN
        RAISE EXCEPTION 'unknown match profile "%"', profile
            USING HINT = 'profiles: ' || (SELECT string_agg(name, ', ' ORDER BY name) FROM modb.match_profiles);
    END IF;
    SELECT string_agg(name, ', ') INTO unknown
      FROM unnest(modb.session_settings()) AS name WHERE substr(name, 6) <> ALL (modb.match_knobs());
    IF unknown IS NOT NULL THEN
        RAISE EXCEPTION 'unknown modb setting: %', unknown
            USING HINT = 'knobs are modb.' || array_to_string(modb.match_knobs(), ', modb.') || '; RESET the unknown one';
    END IF;
    FOREACH knob IN ARRAY modb.match_knobs() LOOP
        value := nullif(current_setting('modb.' || knob, true), '');
        CONTINUE WHEN value IS NULL;
        settings := settings || jsonb_build_object(knob, CASE
            WHEN knob = 'joints' THEN to_jsonb(string_to_array(replace(value, ' ', ''), ','))
            WHEN knob = 'norm' THEN to_jsonb(lower(value))
            WHEN knob = 'velocity_terms' THEN to_jsonb(value::boolean)
            WHEN knob LIKE '%threshold' THEN jsonb_build_object('default', value::float8)  -- one value for every joint
            ELSE to_jsonb(value::float8) END);
    END LOOP;
    joint_names := ARRAY(SELECT jsonb_array_elements_text(settings->'joints'));
    IF joint_names = '{}' OR EXISTS (SELECT FROM unnest(joint_names) j WHERE j <> ALL (names)) THEN
        RAISE EXCEPTION 'profile "%": joints % must be standard joints', profile, joint_names
            USING HINT = 'standard joints: ' || array_to_string(names, ', ');
    END IF;
    IF EXISTS (SELECT FROM jsonb_each(settings) AS e(k, v)
                WHERE k LIKE '%threshold'
                  AND EXISTS (SELECT FROM jsonb_path_query(v, 'strict $.** ? (@.type() == "number")') AS x(n)
                              WHERE NOT (x.n::text::float8 > 0))) THEN
        RAISE EXCEPTION 'profile "%": thresholds must be positive', profile
            USING HINT = 'check SET modb.*_threshold and the profile''s settings';
    END IF;
    IF coalesce((settings->>'heading_weight')::float8, 0) < 0 THEN
        RAISE EXCEPTION 'profile "%": heading_weight must not be negative', profile;
    END IF;
    plan.norm := coalesce(settings->>'norm', 'l2');
    IF plan.norm NOT IN ('l1', 'l2') THEN
        RAISE EXCEPTION 'norm must be l1 or l2, not "%"', plan.norm;
    END IF;
    plan.velocity_terms := coalesce((settings->>'velocity_terms')::boolean, true);
    plan.heading_weight := coalesce((settings->>'heading_weight')::float8, 0);
    plan.joints := ARRAY(SELECT array_position(names, j) - 1 FROM unnest(joint_names) WITH ORDINALITY t(j, n) ORDER BY n);
    plan.position_threshold := modb._thresholds(settings->'position_threshold', names, joint_names);
    plan.angle_threshold := modb._thresholds(settings->'angle_threshold', names, joint_names);
    plan.velocity_threshold := modb._thresholds(settings->'velocity_threshold', names, joint_names);
    plan.angular_velocity_threshold := modb._thresholds(settings->'angular_velocity_threshold', names, joint_names);
    position_by_joint := plan.position_threshold;
    velocity_by_joint := plan.velocity_threshold;
    -- Box half-widths: a feature of an included joint gets that joint's threshold (an L1 or L2 ball
    -- lies inside the box of its radius, so the box loses no candidate); the others are unbounded.
    plan.box_half_width := '{}';
    FOREACH feature IN ARRAY features LOOP
        joint := split_part(feature, '.', 1);
        s := array_position(names, joint);
        plan.box_half_width := plan.box_half_width || CASE
            WHEN joint <> ALL (joint_names) THEN 1e6::float8  -- unbounded, without infinities in the cube
            WHEN split_part(feature, '.', 2) LIKE 'v_' THEN
                CASE WHEN plan.velocity_terms THEN velocity_by_joint[s] ELSE 1e6::float8 END
            ELSE position_by_joint[s] END;
    END LOOP;
    RETURN plan;
END
$$;
COMMENT ON FUNCTION modb.match_plan(text) IS
    'Resolves a match profile with this session''s SET modb.<knob> overrides; an unknown profile or knob is an error';

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

CREATE FUNCTION modb.continuity_ratio(a modb.terminators, b modb.terminators, plan modb.match_plan)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- One expression over every standard joint, written out by build_sql.py so the planner can inline it
-- (an aggregate over unnest() cost ~0.5 ms a row); a joint the profile leaves out has infinite thresholds.
RETURN greatest(
    CASE WHEN (plan).position_threshold[1] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[1] - b.positions[1]) + abs(a.positions[2] - b.positions[2]) + abs(a.positions[3] - b.positions[3]) ELSE sqrt((a.positions[1] - b.positions[1]) ^ 2 + (a.positions[2] - b.positions[2]) ^ 2 + (a.positions[3] - b.positions[3]) ^ 2) END / (plan).position_threshold[1],
        modb.quat_angle(a.rotations[1], a.rotations[2], a.rotations[3], a.rotations[4], b.rotations[1], b.rotations[2], b.rotations[3], b.rotations[4]) / (plan).angle_threshold[1],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[1] - b.velocities[1]) ^ 2 + (a.velocities[2] - b.velocities[2]) ^ 2 + (a.velocities[3] - b.velocities[3]) ^ 2) / (plan).velocity_threshold[1],
             sqrt((a.angular_velocities[1] - b.angular_velocities[1]) ^ 2 + (a.angular_velocities[2] - b.angular_velocities[2]) ^ 2 + (a.angular_velocities[3] - b.angular_velocities[3]) ^ 2) / (plan).angular_velocity_threshold[1]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[2] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[4] - b.positions[4]) + abs(a.positions[5] - b.positions[5]) + abs(a.positions[6] - b.positions[6]) ELSE sqrt((a.positions[4] - b.positions[4]) ^ 2 + (a.positions[5] - b.positions[5]) ^ 2 + (a.positions[6] - b.positions[6]) ^ 2) END / (plan).position_threshold[2],
        modb.quat_angle(a.rotations[5], a.rotations[6], a.rotations[7], a.rotations[8], b.rotations[5], b.rotations[6], b.rotations[7], b.rotations[8]) / (plan).angle_threshold[2],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[4] - b.velocities[4]) ^ 2 + (a.velocities[5] - b.velocities[5]) ^ 2 + (a.velocities[6] - b.velocities[6]) ^ 2) / (plan).velocity_threshold[2],
             sqrt((a.angular_velocities[4] - b.angular_velocities[4]) ^ 2 + (a.angular_velocities[5] - b.angular_velocities[5]) ^ 2 + (a.angular_velocities[6] - b.angular_velocities[6]) ^ 2) / (plan).angular_velocity_threshold[2]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[3] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[7] - b.positions[7]) + abs(a.positions[8] - b.positions[8]) + abs(a.positions[9] - b.positions[9]) ELSE sqrt((a.positions[7] - b.positions[7]) ^ 2 + (a.positions[8] - b.positions[8]) ^ 2 + (a.positions[9] - b.positions[9]) ^ 2) END / (plan).position_threshold[3],
        modb.quat_angle(a.rotations[9], a.rotations[10], a.rotations[11], a.rotations[12], b.rotations[9], b.rotations[10], b.rotations[11], b.rotations[12]) / (plan).angle_threshold[3],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[7] - b.velocities[7]) ^ 2 + (a.velocities[8] - b.velocities[8]) ^ 2 + (a.velocities[9] - b.velocities[9]) ^ 2) / (plan).velocity_threshold[3],
             sqrt((a.angular_velocities[7] - b.angular_velocities[7]) ^ 2 + (a.angular_velocities[8] - b.angular_velocities[8]) ^ 2 + (a.angular_velocities[9] - b.angular_velocities[9]) ^ 2) / (plan).angular_velocity_threshold[3]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[4] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[10] - b.positions[10]) + abs(a.positions[11] - b.positions[11]) + abs(a.positions[12] - b.positions[12]) ELSE sqrt((a.positions[10] - b.positions[10]) ^ 2 + (a.positions[11] - b.positions[11]) ^ 2 + (a.positions[12] - b.positions[12]) ^ 2) END / (plan).position_threshold[4],
        modb.quat_angle(a.rotations[13], a.rotations[14], a.rotations[15], a.rotations[16], b.rotations[13], b.rotations[14], b.rotations[15], b.rotations[16]) / (plan).angle_threshold[4],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[10] - b.velocities[10]) ^ 2 + (a.velocities[11] - b.velocities[11]) ^ 2 + (a.velocities[12] - b.velocities[12]) ^ 2) / (plan).velocity_threshold[4],
             sqrt((a.angular_velocities[10] - b.angular_velocities[10]) ^ 2 + (a.angular_velocities[11] - b.angular_velocities[11]) ^ 2 + (a.angular_velocities[12] - b.angular_velocities[12]) ^ 2) / (plan).angular_velocity_threshold[4]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[5] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[13] - b.positions[13]) + abs(a.positions[14] - b.positions[14]) + abs(a.positions[15] - b.positions[15]) ELSE sqrt((a.positions[13] - b.positions[13]) ^ 2 + (a.positions[14] - b.positions[14]) ^ 2 + (a.positions[15] - b.positions[15]) ^ 2) END / (plan).position_threshold[5],
        modb.quat_angle(a.rotations[17], a.rotations[18], a.rotations[19], a.rotations[20], b.rotations[17], b.rotations[18], b.rotations[19], b.rotations[20]) / (plan).angle_threshold[5],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[13] - b.velocities[13]) ^ 2 + (a.velocities[14] - b.velocities[14]) ^ 2 + (a.velocities[15] - b.velocities[15]) ^ 2) / (plan).velocity_threshold[5],
             sqrt((a.angular_velocities[13] - b.angular_velocities[13]) ^ 2 + (a.angular_velocities[14] - b.angular_velocities[14]) ^ 2 + (a.angular_velocities[15] - b.angular_velocities[15]) ^ 2) / (plan).angular_velocity_threshold[5]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[6] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[16] - b.positions[16]) + abs(a.positions[17] - b.positions[17]) + abs(a.positions[18] - b.positions[18]) ELSE sqrt((a.positions[16] - b.positions[16]) ^ 2 + (a.positions[17] - b.positions[17]) ^ 2 + (a.positions[18] - b.positions[18]) ^ 2) END / (plan).position_threshold[6],
        modb.quat_angle(a.rotations[21], a.rotations[22], a.rotations[23], a.rotations[24], b.rotations[21], b.rotations[22], b.rotations[23], b.rotations[24]) / (plan).angle_threshold[6],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[16] - b.velocities[16]) ^ 2 + (a.velocities[17] - b.velocities[17]) ^ 2 + (a.velocities[18] - b.velocities[18]) ^ 2) / (plan).velocity_threshold[6],
             sqrt((a.angular_velocities[16] - b.angular_velocities[16]) ^ 2 + (a.angular_velocities[17] - b.angular_velocities[17]) ^ 2 + (a.angular_velocities[18] - b.angular_velocities[18]) ^ 2) / (plan).angular_velocity_threshold[6]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[7] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[19] - b.positions[19]) + abs(a.positions[20] - b.positions[20]) + abs(a.positions[21] - b.positions[21]) ELSE sqrt((a.positions[19] - b.positions[19]) ^ 2 + (a.positions[20] - b.positions[20]) ^ 2 + (a.positions[21] - b.positions[21]) ^ 2) END / (plan).position_threshold[7],
        modb.quat_angle(a.rotations[25], a.rotations[26], a.rotations[27], a.rotations[28], b.rotations[25], b.rotations[26], b.rotations[27], b.rotations[28]) / (plan).angle_threshold[7],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[19] - b.velocities[19]) ^ 2 + (a.velocities[20] - b.velocities[20]) ^ 2 + (a.velocities[21] - b.velocities[21]) ^ 2) / (plan).velocity_threshold[7],
             sqrt((a.angular_velocities[19] - b.angular_velocities[19]) ^ 2 + (a.angular_velocities[20] - b.angular_velocities[20]) ^ 2 + (a.angular_velocities[21] - b.angular_velocities[21]) ^ 2) / (plan).angular_velocity_threshold[7]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[8] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[22] - b.positions[22]) + abs(a.positions[23] - b.positions[23]) + abs(a.positions[24] - b.positions[24]) ELSE sqrt((a.positions[22] - b.positions[22]) ^ 2 + (a.positions[23] - b.positions[23]) ^ 2 + (a.positions[24] - b.positions[24]) ^ 2) END / (plan).position_threshold[8],
        modb.quat_angle(a.rotations[29], a.rotations[30], a.rotations[31], a.rotations[32], b.rotations[29], b.rotations[30], b.rotations[31], b.rotations[32]) / (plan).angle_threshold[8],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[22] - b.velocities[22]) ^ 2 + (a.velocities[23] - b.velocities[23]) ^ 2 + (a.velocities[24] - b.velocities[24]) ^ 2) / (plan).velocity_threshold[8],
             sqrt((a.angular_velocities[22] - b.angular_velocities[22]) ^ 2 + (a.angular_velocities[23] - b.angular_velocities[23]) ^ 2 + (a.angular_velocities[24] - b.angular_velocities[24]) ^ 2) / (plan).angular_velocity_threshold[8]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[9] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[25] - b.positions[25]) + abs(a.positions[26] - b.positions[26]) + abs(a.positions[27] - b.positions[27]) ELSE sqrt((a.positions[25] - b.positions[25]) ^ 2 + (a.positions[26] - b.positions[26]) ^ 2 + (a.positions[27] - b.positions[27]) ^ 2) END / (plan).position_threshold[9],
        modb.quat_angle(a.rotations[33], a.rotations[34], a.rotations[35], a.rotations[36], b.rotations[33], b.rotations[34], b.rotations[35], b.rotations[36]) / (plan).angle_threshold[9],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[25] - b.velocities[25]) ^ 2 + (a.velocities[26] - b.velocities[26]) ^ 2 + (a.velocities[27] - b.velocities[27]) ^ 2) / (plan).velocity_threshold[9],
             sqrt((a.angular_velocities[25] - b.angular_velocities[25]) ^ 2 + (a.angular_velocities[26] - b.angular_velocities[26]) ^ 2 + (a.angular_velocities[27] - b.angular_velocities[27]) ^ 2) / (plan).angular_velocity_threshold[9]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[10] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[28] - b.positions[28]) + abs(a.positions[29] - b.positions[29]) + abs(a.positions[30] - b.positions[30]) ELSE sqrt((a.positions[28] - b.positions[28]) ^ 2 + (a.positions[29] - b.positions[29]) ^ 2 + (a.positions[30] - b.positions[30]) ^ 2) END / (plan).position_threshold[10],
        modb.quat_angle(a.rotations[37], a.rotations[38], a.rotations[39], a.rotations[40], b.rotations[37], b.rotations[38], b.rotations[39], b.rotations[40]) / (plan).angle_threshold[10],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[28] - b.velocities[28]) ^ 2 + (a.velocities[29] - b.velocities[29]) ^ 2 + (a.velocities[30] - b.velocities[30]) ^ 2) / (plan).velocity_threshold[10],
             sqrt((a.angular_velocities[28] - b.angular_velocities[28]) ^ 2 + (a.angular_velocities[29] - b.angular_velocities[29]) ^ 2 + (a.angular_velocities[30] - b.angular_velocities[30]) ^ 2) / (plan).angular_velocity_threshold[10]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[11] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[31] - b.positions[31]) + abs(a.positions[32] - b.positions[32]) + abs(a.positions[33] - b.positions[33]) ELSE sqrt((a.positions[31] - b.positions[31]) ^ 2 + (a.positions[32] - b.positions[32]) ^ 2 + (a.positions[33] - b.positions[33]) ^ 2) END / (plan).position_threshold[11],
        modb.quat_angle(a.rotations[41], a.rotations[42], a.rotations[43], a.rotations[44], b.rotations[41], b.rotations[42], b.rotations[43], b.rotations[44]) / (plan).angle_threshold[11],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[31] - b.velocities[31]) ^ 2 + (a.velocities[32] - b.velocities[32]) ^ 2 + (a.velocities[33] - b.velocities[33]) ^ 2) / (plan).velocity_threshold[11],
             sqrt((a.angular_velocities[31] - b.angular_velocities[31]) ^ 2 + (a.angular_velocities[32] - b.angular_velocities[32]) ^ 2 + (a.angular_velocities[33] - b.angular_velocities[33]) ^ 2) / (plan).angular_velocity_threshold[11]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[12] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[34] - b.positions[34]) + abs(a.positions[35] - b.positions[35]) + abs(a.positions[36] - b.positions[36]) ELSE sqrt((a.positions[34] - b.positions[34]) ^ 2 + (a.positions[35] - b.positions[35]) ^ 2 + (a.positions[36] - b.positions[36]) ^ 2) END / (plan).position_threshold[12],
        modb.quat_angle(a.rotations[45], a.rotations[46], a.rotations[47], a.rotations[48], b.rotations[45], b.rotations[46], b.rotations[47], b.rotations[48]) / (plan).angle_threshold[12],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[34] - b.velocities[34]) ^ 2 + (a.velocities[35] - b.velocities[35]) ^ 2 + (a.velocities[36] - b.velocities[36]) ^ 2) / (plan).velocity_threshold[12],
             sqrt((a.angular_velocities[34] - b.angular_velocities[34]) ^ 2 + (a.angular_velocities[35] - b.angular_velocities[35]) ^ 2 + (a.angular_velocities[36] - b.angular_velocities[36]) ^ 2) / (plan).angular_velocity_threshold[12]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[13] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[37] - b.positions[37]) + abs(a.positions[38] - b.positions[38]) + abs(a.positions[39] - b.positions[39]) ELSE sqrt((a.positions[37] - b.positions[37]) ^ 2 + (a.positions[38] - b.positions[38]) ^ 2 + (a.positions[39] - b.positions[39]) ^ 2) END / (plan).position_threshold[13],
        modb.quat_angle(a.rotations[49], a.rotations[50], a.rotations[51], a.rotations[52], b.rotations[49], b.rotations[50], b.rotations[51], b.rotations[52]) / (plan).angle_threshold[13],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[37] - b.velocities[37]) ^ 2 + (a.velocities[38] - b.velocities[38]) ^ 2 + (a.velocities[39] - b.velocities[39]) ^ 2) / (plan).velocity_threshold[13],
             sqrt((a.angular_velocities[37] - b.angular_velocities[37]) ^ 2 + (a.angular_velocities[38] - b.angular_velocities[38]) ^ 2 + (a.angular_velocities[39] - b.angular_velocities[39]) ^ 2) / (plan).angular_velocity_threshold[13]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[14] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[40] - b.positions[40]) + abs(a.positions[41] - b.positions[41]) + abs(a.positions[42] - b.positions[42]) ELSE sqrt((a.positions[40] - b.positions[40]) ^ 2 + (a.positions[41] - b.positions[41]) ^ 2 + (a.positions[42] - b.positions[42]) ^ 2) END / (plan).position_threshold[14],
        modb.quat_angle(a.rotations[53], a.rotations[54], a.rotations[55], a.rotations[56], b.rotations[53], b.rotations[54], b.rotations[55], b.rotations[56]) / (plan).angle_threshold[14],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[40] - b.velocities[40]) ^ 2 + (a.velocities[41] - b.velocities[41]) ^ 2 + (a.velocities[42] - b.velocities[42]) ^ 2) / (plan).velocity_threshold[14],
             sqrt((a.angular_velocities[40] - b.angular_velocities[40]) ^ 2 + (a.angular_velocities[41] - b.angular_velocities[41]) ^ 2 + (a.angular_velocities[42] - b.angular_velocities[42]) ^ 2) / (plan).angular_velocity_threshold[14]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[15] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[43] - b.positions[43]) + abs(a.positions[44] - b.positions[44]) + abs(a.positions[45] - b.positions[45]) ELSE sqrt((a.positions[43] - b.positions[43]) ^ 2 + (a.positions[44] - b.positions[44]) ^ 2 + (a.positions[45] - b.positions[45]) ^ 2) END / (plan).position_threshold[15],
        modb.quat_angle(a.rotations[57], a.rotations[58], a.rotations[59], a.rotations[60], b.rotations[57], b.rotations[58], b.rotations[59], b.rotations[60]) / (plan).angle_threshold[15],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[43] - b.velocities[43]) ^ 2 + (a.velocities[44] - b.velocities[44]) ^ 2 + (a.velocities[45] - b.velocities[45]) ^ 2) / (plan).velocity_threshold[15],
             sqrt((a.angular_velocities[43] - b.angular_velocities[43]) ^ 2 + (a.angular_velocities[44] - b.angular_velocities[44]) ^ 2 + (a.angular_velocities[45] - b.angular_velocities[45]) ^ 2) / (plan).angular_velocity_threshold[15]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[16] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[46] - b.positions[46]) + abs(a.positions[47] - b.positions[47]) + abs(a.positions[48] - b.positions[48]) ELSE sqrt((a.positions[46] - b.positions[46]) ^ 2 + (a.positions[47] - b.positions[47]) ^ 2 + (a.positions[48] - b.positions[48]) ^ 2) END / (plan).position_threshold[16],
        modb.quat_angle(a.rotations[61], a.rotations[62], a.rotations[63], a.rotations[64], b.rotations[61], b.rotations[62], b.rotations[63], b.rotations[64]) / (plan).angle_threshold[16],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[46] - b.velocities[46]) ^ 2 + (a.velocities[47] - b.velocities[47]) ^ 2 + (a.velocities[48] - b.velocities[48]) ^ 2) / (plan).velocity_threshold[16],
             sqrt((a.angular_velocities[46] - b.angular_velocities[46]) ^ 2 + (a.angular_velocities[47] - b.angular_velocities[47]) ^ 2 + (a.angular_velocities[48] - b.angular_velocities[48]) ^ 2) / (plan).angular_velocity_threshold[16]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[17] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[49] - b.positions[49]) + abs(a.positions[50] - b.positions[50]) + abs(a.positions[51] - b.positions[51]) ELSE sqrt((a.positions[49] - b.positions[49]) ^ 2 + (a.positions[50] - b.positions[50]) ^ 2 + (a.positions[51] - b.positions[51]) ^ 2) END / (plan).position_threshold[17],
        modb.quat_angle(a.rotations[65], a.rotations[66], a.rotations[67], a.rotations[68], b.rotations[65], b.rotations[66], b.rotations[67], b.rotations[68]) / (plan).angle_threshold[17],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[49] - b.velocities[49]) ^ 2 + (a.velocities[50] - b.velocities[50]) ^ 2 + (a.velocities[51] - b.velocities[51]) ^ 2) / (plan).velocity_threshold[17],
             sqrt((a.angular_velocities[49] - b.angular_velocities[49]) ^ 2 + (a.angular_velocities[50] - b.angular_velocities[50]) ^ 2 + (a.angular_velocities[51] - b.angular_velocities[51]) ^ 2) / (plan).angular_velocity_threshold[17]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[18] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[52] - b.positions[52]) + abs(a.positions[53] - b.positions[53]) + abs(a.positions[54] - b.positions[54]) ELSE sqrt((a.positions[52] - b.positions[52]) ^ 2 + (a.positions[53] - b.positions[53]) ^ 2 + (a.positions[54] - b.positions[54]) ^ 2) END / (plan).position_threshold[18],
        modb.quat_angle(a.rotations[69], a.rotations[70], a.rotations[71], a.rotations[72], b.rotations[69], b.rotations[70], b.rotations[71], b.rotations[72]) / (plan).angle_threshold[18],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[52] - b.velocities[52]) ^ 2 + (a.velocities[53] - b.velocities[53]) ^ 2 + (a.velocities[54] - b.velocities[54]) ^ 2) / (plan).velocity_threshold[18],
             sqrt((a.angular_velocities[52] - b.angular_velocities[52]) ^ 2 + (a.angular_velocities[53] - b.angular_velocities[53]) ^ 2 + (a.angular_velocities[54] - b.angular_velocities[54]) ^ 2) / (plan).angular_velocity_threshold[18]) ELSE 0 END) END,
    CASE WHEN (plan).position_threshold[19] = 'Infinity' THEN 0 ELSE greatest(
        CASE WHEN (plan).norm = 'l1' THEN abs(a.positions[55] - b.positions[55]) + abs(a.positions[56] - b.positions[56]) + abs(a.positions[57] - b.positions[57]) ELSE sqrt((a.positions[55] - b.positions[55]) ^ 2 + (a.positions[56] - b.positions[56]) ^ 2 + (a.positions[57] - b.positions[57]) ^ 2) END / (plan).position_threshold[19],
        modb.quat_angle(a.rotations[73], a.rotations[74], a.rotations[75], a.rotations[76], b.rotations[73], b.rotations[74], b.rotations[75], b.rotations[76]) / (plan).angle_threshold[19],
        CASE WHEN (plan).velocity_terms THEN greatest(sqrt((a.velocities[55] - b.velocities[55]) ^ 2 + (a.velocities[56] - b.velocities[56]) ^ 2 + (a.velocities[57] - b.velocities[57]) ^ 2) / (plan).velocity_threshold[19],
             sqrt((a.angular_velocities[55] - b.angular_velocities[55]) ^ 2 + (a.angular_velocities[56] - b.angular_velocities[56]) ^ 2 + (a.angular_velocities[57] - b.angular_velocities[57]) ^ 2) / (plan).angular_velocity_threshold[19]) ELSE 0 END) END);
COMMENT ON FUNCTION modb.continuity_ratio(modb.terminators, modb.terminators, modb.match_plan) IS
    'max over included joints of difference/threshold (position by the profile''s norm, quaternion angle, velocities): <= 1 within thresholds';

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

-- 74_build.sql
CREATE OR REPLACE FUNCTION modb.build_snippets(collection text DEFAULT NULL, clip bigint DEFAULT NULL,
                                    window_seconds float8 DEFAULT 0.5, stride_seconds float8 DEFAULT 1.0 / 30,
                                    mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
kernel = GD.get('modb_kernel 0.2.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. A joint c\nwith parent j then takes the rotation M_j R_c M_c, where M_j is a reflection in joint j\'s rest frame\nthat maps j\'s children\'s offsets onto their partners\' (M_j off_c = off_m(c)), and the root\'s parent\nreflection is S itself. A translated joint\'s translation becomes M_j t_c, which keeps its world position\nexact whatever M_j is; a fixed offset stays exact as far as the captured skeleton is symmetric.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _project_out(n, vectors):\n    """n minus its components along each of `vectors` (zero vectors ignored)."""\n    n = np.array(n, dtype=np.float64)\n    for v in vectors:\n        norm = np.linalg.norm(v)\n        if norm > 1e-9:\n            n = n - np.dot(n, v / norm) * (v / norm)\n    return n\n\n\ndef _perpendicular(reference, vectors):\n    """The unit vector nearest `reference` perpendicular to every one of `vectors`."""\n    for start in (reference, *np.eye(3)):  # if reference is spanned by them, any perpendicular will do\n        n = _project_out(start, vectors)\n        if np.linalg.norm(n) > 1e-9:\n            break\n    return n / np.linalg.norm(n)\n\n\ndef _direction_difference(a, b):\n    """a/|a| - b/|b|: the reflection along it maps the direction of a onto b\'s exactly, even when a captured\n    skeleton\'s two sides differ a little in length (CMU 131\'s toes: 12.8 and 11.9 cm)."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    if np.linalg.norm(a) < 1e-9 or np.linalg.norm(b) < 1e-9:\n        return np.zeros(3)\n    return a / np.linalg.norm(a) - b / np.linalg.norm(b)\n\n\ndef reflection_normals(parents, offsets, end_sites, partner):\n    """Per joint, the normal of the reflection M_j of its rest frame (see the module docstring)."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    normals = np.zeros((n_joints, 3))\n    for j in range(n_joints):\n        if partner[j] < j:  # the right side of a pair takes its left partner\'s reflection\n            normals[j] = normals[partner[j]]\n            continue\n        d = np.zeros(3)\n        for c in children[j]:\n            diff = _direction_difference(offsets[c], offsets[partner[c]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if end_sites[j] is not None and end_sites[partner[j]] is not None:\n            diff = _direction_difference(end_sites[j], end_sites[partner[j]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if np.linalg.norm(d) > 1e-6:\n            normals[j] = d / np.linalg.norm(d)\n        else:\n            reference = normals[parents[j]] if parents[j] >= 0 else np.array([1.0, 0.0, 0.0])\n            kept = [offsets[c] for c in children[j]]\n            if end_sites[j] is not None:\n                kept.append(np.asarray(end_sites[j], dtype=np.float64))\n            normals[j] = _perpendicular(reference, kept)\n    return normals\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    normals = reflection_normals(parents, offsets, end_sites, partner)\n    reflect = np.eye(3) - 2.0 * normals[:, :, None] * normals[:, None, :]  # (J, 3, 3)\n    world = np.diag([-1.0, 1.0, 1.0])\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = world if p < 0 else reflect[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ reflect[c])\n    out_translations = np.array(translations, dtype=np.float64, copy=True) if len(translated) else translations\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        p = parents[c]\n        above = world if p < 0 else reflect[p]\n        out_translations[:, slot[partner[c]]] = np.asarray(translations, dtype=np.float64)[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _inverse(q):\n    return q * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = _inverse(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(_inverse(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], _inverse(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = _inverse(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_2_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.2.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_2_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_2_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_2_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.2.0'] = kernel
import json
import numpy as np

T = kernel.terminators
if not (window_seconds and window_seconds > 0 and stride_seconds and stride_seconds > 0):
    plpy.error("window_seconds and stride_seconds must be positive")
collections = None
if collection is not None:
    collections = plpy.execute(plpy.prepare("SELECT modb.collection_subtree($1) AS ids", ["text"]), [collection])[0]["ids"]
    if not collections:
        plpy.error(f'no collection "{collection}"', hint="modb.collection_path(id) names the stored ones")
todo = plpy.cursor(plpy.prepare(
    """SELECT v.clip_id, v.version, v.fps, v.rotations, v.translations, s.id AS skeleton_id, s.hierarchy,
              s.joint_map, s.mirror_pairs, c.collection_id, c.name, modb.skeleton_pose_key(s.hierarchy) AS pose_key
         FROM modb.clip_versions v
         JOIN modb.clips c ON c.id = v.clip_id
         JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.version = (SELECT max(version) FROM modb.clip_versions x WHERE x.clip_id = v.clip_id)
          AND ($1::bigint[] IS NULL OR c.collection_id = ANY ($1))
          AND ($2::bigint IS NULL OR c.id = $2)
          AND NOT EXISTS (SELECT FROM modb.snippet_sources ss
                           WHERE ss.clip_id = v.clip_id AND ss.version = v.version AND ss.mirrored = $3)
        ORDER BY v.clip_id""", ["bigint[]", "bigint", "boolean"]), [collections, clip, bool(mirrored)])
drop_old = plpy.prepare(
    "DELETE FROM modb.snippet_sources WHERE clip_id = $1 AND version < $2 RETURNING mirrored", ["bigint", "int"])
built = plpy.prepare("SELECT mirrored FROM modb.snippet_sources WHERE clip_id = $1 AND version = $2",
                     ["bigint", "int"])
add_source = plpy.prepare(
    "INSERT INTO modb.snippet_sources (clip_id, version, mirrored, window_frames, stride_frames) "
    "VALUES ($1, $2, $5, $3, $4)", ["bigint", "int", "int", "int", "boolean"])
add_terminators = plpy.prepare(
    """INSERT INTO modb.terminators (clip_id, version, mirrored, frame, heading, pelvis_height, positions,
                                     rotations, velocities, angular_velocities, configuration, features)
       SELECT $1, $2, $4, r.frame, r.heading, r.pelvis_height, r.positions, r.rotations, r.velocities,
              r.angular_velocities, r.configuration, cube(r.features)
         FROM jsonb_to_recordset($3::jsonb) AS r(frame int, heading float8, pelvis_height real, positions real[],
              rotations real[], velocities real[], angular_velocities real[], configuration real[][], features float8[])
       RETURNING frame, id""", ["bigint", "int", "text", "boolean"])
add_snippets = plpy.prepare(
    """INSERT INTO modb.snippets (clip_id, version, mirrored, first_frame, n_frames, collection_id, pose_key, fps,
                                  begin_terminator, end_terminator, begin_features, net_translation, net_heading,
                                  net_rotation)
       SELECT $1, $2, $8, r.first_frame, $3, $4, $5, $6, r.begin_terminator, r.end_terminator, t.features,
              r.net_translation, r.net_heading, r.net_rotation
         FROM jsonb_to_recordset($7::jsonb) AS r(first_frame int, begin_terminator bigint, end_terminator bigint,
              net_translation float8[], net_heading float8, net_rotation float8[])
         JOIN modb.terminators t ON t.id = r.begin_terminator
        ORDER BY r.first_frame""",
    ["bigint", "int", "int", "bigint", "text", "float8", "text", "boolean"])

def flat(a):
    return np.asarray(a, dtype=np.float64).reshape(len(a), -1).tolist()

added = 0
while True:
    rows = todo.fetch(1)
    if not rows:
        break
    row = rows[0]
    h = json.loads(row["hierarchy"])
    names = [j["name"] for j in h["joints"]]
    try:
        std = T.standard_indices(names, json.loads(row["joint_map"]))
    except T.SkeletonMapError as e:
        plpy.error(f'clip {row["clip_id"]} ({row["name"]}): skeleton {row["skeleton_id"]}: {e}',
                   hint="complete modb.skeletons.joint_map for it, then call modb.build_snippets again")
    captured = np.asarray(row["rotations"], dtype=np.float64)
    firsts, length, stride = T.windows(len(captured), row["fps"], window_seconds, stride_seconds)
    # A new version replaces the old versions' snippets, and keeps their mirror images if they had them.
    old_flags = {r["mirrored"] for r in plpy.execute(drop_old, [row["clip_id"], row["version"]])}
    existing = {r["mirrored"] for r in plpy.execute(built, [row["clip_id"], row["version"]])}
    parents = [j["parent"] for j in h["joints"]]
    offsets = [j["offset"] for j in h["joints"]]
    for flag in sorted(({bool(mirrored)} | old_flags) - existing):
        plpy.execute(add_source, [row["clip_id"], row["version"], length, stride, flag])
        if len(firsts) == 0:
            continue  # shorter than one snippet: recorded as built, nothing to add
        rotations, translations = captured, row["translations"]
        if flag:
            pairs = json.loads(row["mirror_pairs"])
            if not pairs:
                plpy.error(f'clip {row["clip_id"]} ({row["name"]}): skeleton {row["skeleton_id"]} has no mirror pairs',
                           hint="fill modb.skeletons.mirror_pairs with its [left, right] joints")
            rotations, translations = kernel.mirror.mirror(
                parents, offsets, [j["end_site"] for j in h["joints"]], kernel.mirror.partner_index(names, pairs),
                rotations, translations, h["translated"])
        terms = T.compute(parents, offsets, rotations, translations, h["translated"], std, row["fps"])
        frames = sorted(set(firsts.tolist()) | set((firsts + length - 1).tolist()))
        pick = {k: flat(terms[k][frames]) for k in ("positions", "rotations", "velocities", "angular_velocities", "features")}
        configuration = terms["configuration"][frames].tolist()
        records = [{"frame": f, "heading": float(terms["heading"][f]), "pelvis_height": float(terms["pelvis_height"][f]),
                    "positions": pick["positions"][i], "rotations": pick["rotations"][i],
                    "velocities": pick["velocities"][i], "angular_velocities": pick["angular_velocities"][i],
                    "configuration": configuration[i], "features": pick["features"][i]}
                   for i, f in enumerate(frames)]
        ids = {r["frame"]: r["id"] for r in plpy.execute(add_terminators, [row["clip_id"], row["version"],
                                                                          json.dumps(records), flag])}
        snippets = []
        for first in firsts.tolist():
            last = first + length - 1
            translation, turn, rotation = T.net_motion(terms, first, last)
            snippets.append({"first_frame": first, "begin_terminator": ids[first], "end_terminator": ids[last],
                             "net_translation": translation.tolist(), "net_heading": float(turn),
                             "net_rotation": rotation.tolist()})
        plpy.execute(add_snippets, [row["clip_id"], row["version"], length, row["collection_id"], row["pose_key"],
                                    row["fps"], json.dumps(snippets), flag])
        added += len(snippets)
return added
$py$;
COMMENT ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) IS
    'Cuts the newest version of every clip in scope (a collection''s subtree, one clip, or all) that has no snippets yet into windows of window_seconds starting every stride_seconds, with their terminators; drops the snippets of older versions. mirrored => true adds the clips'' mirror images (through the skeleton''s mirror_pairs) as further sources. Returns the number of snippets added';

REVOKE EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) TO modb_loader;

-- 76_select.sql
-- select_next_snippet: continuity (WHERE) and objective (ORDER BY) as one query the planner sees whole.
-- LANGUAGE sql, STABLE, not STRICT, one SELECT: inlined into the caller's plan, so EXPLAIN shows the
-- GiST index scan on snippets.begin_features with the profile's box as its Index Cond.

CREATE FUNCTION modb.select_next_snippets(prev_snippet bigint, target float8[], k int,
                                          profile text DEFAULT 'default', collection text DEFAULT NULL,
                                          exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
WITH cfg AS MATERIALIZED (
    SELECT modb.match_plan(profile) AS plan, modb.check_request(prev_snippet, target, k, collection) AS checked,
           CASE WHEN collection IS NULL THEN NULL ELSE modb.collection_subtree(collection) END AS collections
), prev AS MATERIALIZED (
    SELECT t AS term, t.features, s.pose_key, s.fps
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator
     WHERE s.id = prev_snippet
       AND (SELECT checked FROM cfg)  -- every path reads prev or cfg first: bad requests always raise
), candidates AS NOT MATERIALIZED (
    -- The filters every level shares: same skeleton poses and rate, the collection, and no replay of a
    -- frame the previous snippet or a recent one covered (its first frame, the seam, aside).
    SELECT s.*
      FROM modb.snippets s
     WHERE (collection IS NULL OR s.collection_id = ANY ((SELECT collections FROM cfg)::bigint[]))
       AND NOT EXISTS (SELECT FROM modb.snippets x
                        WHERE (x.id = ANY (exclude) OR x.id = prev_snippet)
                          AND x.clip_id = s.clip_id AND x.version = s.version
                          AND x.mirrored = s.mirrored
                          AND x.first_frame + 1 <= s.first_frame + s.n_frames - 1
                          AND s.first_frame + 1 <= x.first_frame + x.n_frames - 1)
)
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)) AS proximity,
        0, NULL::float8, c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c
  WHERE prev_snippet IS NULL AND (SELECT checked FROM cfg)
  ORDER BY 7, 1 LIMIT k)
-- Relaxation levels 0-3: every threshold (and the box) scaled by 2^level; a row reports the lowest
-- level it satisfies. Level 4, the last: the nearest start configuration (feature distance), any ratio.
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)), 0, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 1.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 1.0
  ORDER BY 7, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)), 1, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 2.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 2.0 AND r.ratio > 1.0
  ORDER BY 7, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)), 2, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 4.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 4.0 AND r.ratio > 2.0
  ORDER BY 7, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)), 3, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 8.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 8.0 AND r.ratio > 4.0
  ORDER BY 7, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.target_cost(c.net_translation, c.net_heading, target, (SELECT (plan).heading_weight FROM cfg)),
        4, modb.continuity_ratio(prev.term, b, cfg.plan),
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg
  WHERE prev_snippet IS NOT NULL
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND modb.continuity_ratio(prev.term, b, cfg.plan) > 8
  ORDER BY c.begin_features <-> (SELECT features FROM prev), c.id LIMIT k)
LIMIT k
$$;
COMMENT ON FUNCTION modb.select_next_snippets(bigint, float8[], int, text, text, bigint[]) IS
    'The k best continuations of prev_snippet toward target ({x, z} or {x, y, z}, metres, in the avatar''s heading frame at its end), ordered by relaxation level then proximity; prev_snippet NULL: the snippets that best serve the target';

CREATE FUNCTION modb.select_next_snippet(prev_snippet bigint, target float8[], profile text DEFAULT 'default',
                                         collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT * FROM modb.select_next_snippets(prev_snippet, target, 1, profile, collection, exclude)
$$;
COMMENT ON FUNCTION modb.select_next_snippet(bigint, float8[], text, text, bigint[]) IS
    'The snippet that continues prev_snippet smoothly (the profile''s thresholds, relaxed in steps when nothing passes) and brings the avatar nearest to target ({x, z} or {x, y, z} metres in its heading frame at the end of prev_snippet; x left, z forward). prev_snippet NULL: the snippet that best serves the target. exclude: recently played snippets, whose frames are not replayed';

CREATE FUNCTION modb.world_to_local(origin float8[], heading float8, target_world float8[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- Heading theta faces (sin theta, 0, cos theta); the character's left is (cos theta, 0, -sin theta).
RETURN CASE WHEN array_length(target_world, 1) = 3
    THEN ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[3] - origin[3]) * sin(heading),
               target_world[2] - origin[2],
               (target_world[1] - origin[1]) * sin(heading) + (target_world[3] - origin[3]) * cos(heading)]
    ELSE ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[2] - origin[3]) * sin(heading),
               (target_world[1] - origin[1]) * sin(heading) + (target_world[2] - origin[3]) * cos(heading)] END;
COMMENT ON FUNCTION modb.world_to_local(float8[], float8, float8[]) IS
    'A world target ({x, z} on the ground or {x, y, z}) in the heading frame of a character at origin {x, y, z} with heading theta';

CREATE FUNCTION modb.select_next_snippet_world(prev_snippet bigint, "position" float8[], heading float8,
                                               target_world float8[], profile text DEFAULT 'default',
                                               collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT * FROM modb.select_next_snippets(prev_snippet, modb.world_to_local(select_next_snippet_world."position", heading, target_world), 1,
                                         profile, collection, exclude)
$$;
COMMENT ON FUNCTION modb.select_next_snippet_world(bigint, float8[], float8, float8[], text, text, bigint[]) IS
    'select_next_snippet with the goal in world coordinates: the avatar at position {x, y, z} with heading theta (radians, 0 = facing +Z)';

-- PL/Python functions re-created with the 0.2.0 kernel
CREATE OR REPLACE FUNCTION modb.unit_quaternions_ok(rotations real[], tolerance float8 DEFAULT 1e-5)
RETURNS boolean
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.2.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. A joint c\nwith parent j then takes the rotation M_j R_c M_c, where M_j is a reflection in joint j\'s rest frame\nthat maps j\'s children\'s offsets onto their partners\' (M_j off_c = off_m(c)), and the root\'s parent\nreflection is S itself. A translated joint\'s translation becomes M_j t_c, which keeps its world position\nexact whatever M_j is; a fixed offset stays exact as far as the captured skeleton is symmetric.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _project_out(n, vectors):\n    """n minus its components along each of `vectors` (zero vectors ignored)."""\n    n = np.array(n, dtype=np.float64)\n    for v in vectors:\n        norm = np.linalg.norm(v)\n        if norm > 1e-9:\n            n = n - np.dot(n, v / norm) * (v / norm)\n    return n\n\n\ndef _perpendicular(reference, vectors):\n    """The unit vector nearest `reference` perpendicular to every one of `vectors`."""\n    for start in (reference, *np.eye(3)):  # if reference is spanned by them, any perpendicular will do\n        n = _project_out(start, vectors)\n        if np.linalg.norm(n) > 1e-9:\n            break\n    return n / np.linalg.norm(n)\n\n\ndef _direction_difference(a, b):\n    """a/|a| - b/|b|: the reflection along it maps the direction of a onto b\'s exactly, even when a captured\n    skeleton\'s two sides differ a little in length (CMU 131\'s toes: 12.8 and 11.9 cm)."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    if np.linalg.norm(a) < 1e-9 or np.linalg.norm(b) < 1e-9:\n        return np.zeros(3)\n    return a / np.linalg.norm(a) - b / np.linalg.norm(b)\n\n\ndef reflection_normals(parents, offsets, end_sites, partner):\n    """Per joint, the normal of the reflection M_j of its rest frame (see the module docstring)."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    normals = np.zeros((n_joints, 3))\n    for j in range(n_joints):\n        if partner[j] < j:  # the right side of a pair takes its left partner\'s reflection\n            normals[j] = normals[partner[j]]\n            continue\n        d = np.zeros(3)\n        for c in children[j]:\n            diff = _direction_difference(offsets[c], offsets[partner[c]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if end_sites[j] is not None and end_sites[partner[j]] is not None:\n            diff = _direction_difference(end_sites[j], end_sites[partner[j]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if np.linalg.norm(d) > 1e-6:\n            normals[j] = d / np.linalg.norm(d)\n        else:\n            reference = normals[parents[j]] if parents[j] >= 0 else np.array([1.0, 0.0, 0.0])\n            kept = [offsets[c] for c in children[j]]\n            if end_sites[j] is not None:\n                kept.append(np.asarray(end_sites[j], dtype=np.float64))\n            normals[j] = _perpendicular(reference, kept)\n    return normals\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    normals = reflection_normals(parents, offsets, end_sites, partner)\n    reflect = np.eye(3) - 2.0 * normals[:, :, None] * normals[:, None, :]  # (J, 3, 3)\n    world = np.diag([-1.0, 1.0, 1.0])\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = world if p < 0 else reflect[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ reflect[c])\n    out_translations = np.array(translations, dtype=np.float64, copy=True) if len(translated) else translations\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        p = parents[c]\n        above = world if p < 0 else reflect[p]\n        out_translations[:, slot[partner[c]]] = np.asarray(translations, dtype=np.float64)[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _inverse(q):\n    return q * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = _inverse(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(_inverse(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], _inverse(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = _inverse(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_2_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.2.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_2_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_2_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_2_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.2.0'] = kernel
return kernel.validate.unit_quaternions_ok(rotations, tolerance)
$py$;

CREATE OR REPLACE FUNCTION modb.finite_ok(elements real[])
RETURNS boolean
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.2.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. A joint c\nwith parent j then takes the rotation M_j R_c M_c, where M_j is a reflection in joint j\'s rest frame\nthat maps j\'s children\'s offsets onto their partners\' (M_j off_c = off_m(c)), and the root\'s parent\nreflection is S itself. A translated joint\'s translation becomes M_j t_c, which keeps its world position\nexact whatever M_j is; a fixed offset stays exact as far as the captured skeleton is symmetric.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _project_out(n, vectors):\n    """n minus its components along each of `vectors` (zero vectors ignored)."""\n    n = np.array(n, dtype=np.float64)\n    for v in vectors:\n        norm = np.linalg.norm(v)\n        if norm > 1e-9:\n            n = n - np.dot(n, v / norm) * (v / norm)\n    return n\n\n\ndef _perpendicular(reference, vectors):\n    """The unit vector nearest `reference` perpendicular to every one of `vectors`."""\n    for start in (reference, *np.eye(3)):  # if reference is spanned by them, any perpendicular will do\n        n = _project_out(start, vectors)\n        if np.linalg.norm(n) > 1e-9:\n            break\n    return n / np.linalg.norm(n)\n\n\ndef _direction_difference(a, b):\n    """a/|a| - b/|b|: the reflection along it maps the direction of a onto b\'s exactly, even when a captured\n    skeleton\'s two sides differ a little in length (CMU 131\'s toes: 12.8 and 11.9 cm)."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    if np.linalg.norm(a) < 1e-9 or np.linalg.norm(b) < 1e-9:\n        return np.zeros(3)\n    return a / np.linalg.norm(a) - b / np.linalg.norm(b)\n\n\ndef reflection_normals(parents, offsets, end_sites, partner):\n    """Per joint, the normal of the reflection M_j of its rest frame (see the module docstring)."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    normals = np.zeros((n_joints, 3))\n    for j in range(n_joints):\n        if partner[j] < j:  # the right side of a pair takes its left partner\'s reflection\n            normals[j] = normals[partner[j]]\n            continue\n        d = np.zeros(3)\n        for c in children[j]:\n            diff = _direction_difference(offsets[c], offsets[partner[c]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if end_sites[j] is not None and end_sites[partner[j]] is not None:\n            diff = _direction_difference(end_sites[j], end_sites[partner[j]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if np.linalg.norm(d) > 1e-6:\n            normals[j] = d / np.linalg.norm(d)\n        else:\n            reference = normals[parents[j]] if parents[j] >= 0 else np.array([1.0, 0.0, 0.0])\n            kept = [offsets[c] for c in children[j]]\n            if end_sites[j] is not None:\n                kept.append(np.asarray(end_sites[j], dtype=np.float64))\n            normals[j] = _perpendicular(reference, kept)\n    return normals\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    normals = reflection_normals(parents, offsets, end_sites, partner)\n    reflect = np.eye(3) - 2.0 * normals[:, :, None] * normals[:, None, :]  # (J, 3, 3)\n    world = np.diag([-1.0, 1.0, 1.0])\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = world if p < 0 else reflect[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ reflect[c])\n    out_translations = np.array(translations, dtype=np.float64, copy=True) if len(translated) else translations\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        p = parents[c]\n        above = world if p < 0 else reflect[p]\n        out_translations[:, slot[partner[c]]] = np.asarray(translations, dtype=np.float64)[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _inverse(q):\n    return q * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = _inverse(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(_inverse(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], _inverse(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = _inverse(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_2_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.2.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_2_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_2_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_2_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.2.0'] = kernel
return kernel.validate.finite_ok(elements)
$py$;

CREATE OR REPLACE FUNCTION modb.forward_kinematics(hierarchy jsonb, rotations real[], translations real[])
RETURNS TABLE (frame int, joint_index int, joint text, x float8, y float8, z float8)
LANGUAGE plpython3u IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.2.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. A joint c\nwith parent j then takes the rotation M_j R_c M_c, where M_j is a reflection in joint j\'s rest frame\nthat maps j\'s children\'s offsets onto their partners\' (M_j off_c = off_m(c)), and the root\'s parent\nreflection is S itself. A translated joint\'s translation becomes M_j t_c, which keeps its world position\nexact whatever M_j is; a fixed offset stays exact as far as the captured skeleton is symmetric.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _project_out(n, vectors):\n    """n minus its components along each of `vectors` (zero vectors ignored)."""\n    n = np.array(n, dtype=np.float64)\n    for v in vectors:\n        norm = np.linalg.norm(v)\n        if norm > 1e-9:\n            n = n - np.dot(n, v / norm) * (v / norm)\n    return n\n\n\ndef _perpendicular(reference, vectors):\n    """The unit vector nearest `reference` perpendicular to every one of `vectors`."""\n    for start in (reference, *np.eye(3)):  # if reference is spanned by them, any perpendicular will do\n        n = _project_out(start, vectors)\n        if np.linalg.norm(n) > 1e-9:\n            break\n    return n / np.linalg.norm(n)\n\n\ndef _direction_difference(a, b):\n    """a/|a| - b/|b|: the reflection along it maps the direction of a onto b\'s exactly, even when a captured\n    skeleton\'s two sides differ a little in length (CMU 131\'s toes: 12.8 and 11.9 cm)."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    if np.linalg.norm(a) < 1e-9 or np.linalg.norm(b) < 1e-9:\n        return np.zeros(3)\n    return a / np.linalg.norm(a) - b / np.linalg.norm(b)\n\n\ndef reflection_normals(parents, offsets, end_sites, partner):\n    """Per joint, the normal of the reflection M_j of its rest frame (see the module docstring)."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    normals = np.zeros((n_joints, 3))\n    for j in range(n_joints):\n        if partner[j] < j:  # the right side of a pair takes its left partner\'s reflection\n            normals[j] = normals[partner[j]]\n            continue\n        d = np.zeros(3)\n        for c in children[j]:\n            diff = _direction_difference(offsets[c], offsets[partner[c]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if end_sites[j] is not None and end_sites[partner[j]] is not None:\n            diff = _direction_difference(end_sites[j], end_sites[partner[j]])\n            d += diff if np.dot(diff, d) >= 0 else -diff\n        if np.linalg.norm(d) > 1e-6:\n            normals[j] = d / np.linalg.norm(d)\n        else:\n            reference = normals[parents[j]] if parents[j] >= 0 else np.array([1.0, 0.0, 0.0])\n            kept = [offsets[c] for c in children[j]]\n            if end_sites[j] is not None:\n                kept.append(np.asarray(end_sites[j], dtype=np.float64))\n            normals[j] = _perpendicular(reference, kept)\n    return normals\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    normals = reflection_normals(parents, offsets, end_sites, partner)\n    reflect = np.eye(3) - 2.0 * normals[:, :, None] * normals[:, None, :]  # (J, 3, 3)\n    world = np.diag([-1.0, 1.0, 1.0])\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = world if p < 0 else reflect[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ reflect[c])\n    out_translations = np.array(translations, dtype=np.float64, copy=True) if len(translated) else translations\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        p = parents[c]\n        above = world if p < 0 else reflect[p]\n        out_translations[:, slot[partner[c]]] = np.asarray(translations, dtype=np.float64)[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _inverse(q):\n    return q * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = _inverse(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(_inverse(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], _inverse(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = _inverse(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_2_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.2.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_2_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_2_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_2_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.2.0'] = kernel
import json
import numpy as np
if hierarchy is None or rotations is None:
    return []
h = json.loads(hierarchy)
joints = h["joints"]
positions = kernel.kinematics.world_positions(
    [j["parent"] for j in joints], [j["offset"] for j in joints],
    np.asarray(rotations, dtype=np.float64), translations, h["translated"])
names = [j["name"] for j in joints]
n_frames, n_joints = positions.shape[:2]
flat = positions.reshape(-1, 3).tolist()
return ((f, j, names[j], *flat[f * n_joints + j]) for f in range(n_frames) for j in range(n_joints))
$py$;
