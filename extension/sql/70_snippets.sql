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
    features           cube NOT NULL CONSTRAINT terminators_features_check CHECK (cube_dim(features) = 49),
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
    'The indexed feature vector, physical units: modb.feature_names() lists its 49 dimensions';

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
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE,
    future_translation float8[] CHECK (array_length(future_translation, 1) = 3),
    future_heading     float8
);
COMMENT ON TABLE modb.snippets IS
    'SnippetDescriptor: frames first_frame .. first_frame + n_frames - 1 of a clip version; played after another snippet, its first frame stands in for that one''s last';
COMMENT ON COLUMN modb.snippets.begin_features IS 'Copy of the begin terminator''s features, so the GiST index serves the selection alone';
COMMENT ON COLUMN modb.snippets.net_translation IS 'Pelvis travel (x left, y up, z forward; metres) in the heading frame of the first frame';
COMMENT ON COLUMN modb.snippets.net_heading IS 'Heading change over the snippet (radians, counter-clockwise seen from above)';
COMMENT ON COLUMN modb.snippets.net_rotation IS 'The heading change as a unit quaternion (w, x, y, z) about +Y';
COMMENT ON COLUMN modb.snippets.future_translation IS
    'Where playing on leads: pelvis travel over this snippet and up to two play-on snippets of its clip (1.5 s for 0.5 s windows), in the heading frame of its first frame; the objective of select_next_snippet';
COMMENT ON COLUMN modb.snippets.future_heading IS 'The heading change over the same frames as future_translation (radians)';

-- The feature index's operator class: 71_snippets_index.sql
CREATE INDEX snippets_clip_idx ON modb.snippets (clip_id, version, mirrored, first_frame);
CREATE INDEX snippets_pose_key_idx ON modb.snippets (pose_key, fps);
-- For the foreign keys: deleting a clip version's terminators must not scan every snippet per row.
CREATE INDEX snippets_begin_terminator_idx ON modb.snippets (begin_terminator);
CREATE INDEX snippets_end_terminator_idx ON modb.snippets (end_terminator);

SELECT pg_catalog.pg_extension_config_dump('modb.snippet_sources', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets_id_seq', '');

GRANT SELECT ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_reader;
-- The loader adds snippets and fills their futures; an old version's snippets and terminators go with its
-- snippet_sources row (ON DELETE CASCADE runs as the tables' owner). No table-level DELETE or UPDATE on
-- the tables the selection reads: either would also let the role LOCK them against every reader.
GRANT INSERT ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_loader;
GRANT DELETE ON modb.snippet_sources TO modb_loader;
GRANT UPDATE (future_translation, future_heading) ON modb.snippets TO modb_loader;
GRANT USAGE ON modb.terminators_id_seq, modb.snippets_id_seq TO modb_loader;
