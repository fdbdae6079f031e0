-- The motion data model, after the DFKI motion database: collections (a hierarchy),
-- skeletons, clips with immutable versions, and jsonb models and graphs.

CREATE TABLE modb.collections (
    id         bigserial PRIMARY KEY,
    parent_id  bigint REFERENCES modb.collections (id) CHECK (parent_id <> id),
    name       text NOT NULL CHECK (name ~ '^[^/]+$'),
    meta       jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at timestamptz NOT NULL DEFAULT now(),
    UNIQUE NULLS NOT DISTINCT (parent_id, name)
);
COMMENT ON TABLE modb.collections IS 'A hierarchy of collections; a path like "bandai/walks" names one';
COMMENT ON COLUMN modb.collections.parent_id IS 'Enclosing collection, NULL at the top';

CREATE TABLE modb.skeletons (
    id               bigserial PRIMARY KEY,
    name             text NOT NULL,
    hierarchy        jsonb NOT NULL CHECK (jsonb_typeof(hierarchy->'joints') = 'array'
                                           AND jsonb_array_length(hierarchy->'joints') > 0
                                           AND jsonb_typeof(hierarchy->'unit_m') = 'number'),
    identity_sha256  text NOT NULL GENERATED ALWAYS AS (modb.skeleton_identity(hierarchy)) STORED UNIQUE,
    joint_map        jsonb NOT NULL DEFAULT '{}',
    mirror_pairs     jsonb NOT NULL DEFAULT '[]',
    meta             jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at       timestamptz NOT NULL DEFAULT now(),
    CONSTRAINT skeletons_joint_map_check CHECK (modb.joint_map_ok(hierarchy, joint_map)),
    CONSTRAINT skeletons_mirror_pairs_check CHECK (modb.mirror_pairs_ok(hierarchy, mirror_pairs))
);
COMMENT ON TABLE modb.skeletons IS
    'Joint hierarchies as loaded; hierarchies equal up to offsets their position channels replace are stored once (identity_sha256)';
COMMENT ON COLUMN modb.skeletons.hierarchy IS
    'Immutable: {"format", "unit_m" (metres per source unit), "joints": [{"name", "parent" (index, -1 for the root), "offset" (metres), "channels" (as loaded), "rotation_order", "end_site"}], "translated" (indices of joints with position channels), "rest_positions" (metres)}';
COMMENT ON COLUMN modb.skeletons.joint_map IS
    'Editable: standard joint name (pelvis, spine, chest, neck, head, left_/right_ hip, knee, ankle, toe, shoulder, elbow, wrist) -> joint name; pelvis carries the body''s travel';
COMMENT ON COLUMN modb.skeletons.mirror_pairs IS 'Editable: [[left, right], ...] for every sided joint, used for mirroring';

CREATE TABLE modb.clips (
    id            bigserial PRIMARY KEY,
    collection_id bigint NOT NULL REFERENCES modb.collections (id),
    name          text NOT NULL CHECK (name <> ''),
    meta          jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at    timestamptz NOT NULL DEFAULT now(),
    UNIQUE (collection_id, name)
);
COMMENT ON TABLE modb.clips IS 'A clip''s identity; its motion is in modb.clip_versions, the newest version being "the clip"';

CREATE TABLE modb.clip_versions (
    clip_id       bigint NOT NULL REFERENCES modb.clips (id) ON DELETE CASCADE,
    version       int NOT NULL CHECK (version > 0),
    skeleton_id   bigint NOT NULL REFERENCES modb.skeletons (id),
    fps           float8 NOT NULL CHECK (fps > 0 AND fps < 'Infinity'),
    n_frames      int NOT NULL CHECK (n_frames > 0),
    rotations     real[] NOT NULL,
    translations  real[],
    source_file   text,
    source_sha256 text CHECK (source_sha256 ~ '^[0-9a-f]{64}$'),
    load_params   jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(load_params) = 'object'),
    meta          jsonb NOT NULL DEFAULT '{}',
    created_at    timestamptz NOT NULL DEFAULT now(),
    created_by    name NOT NULL DEFAULT current_user,
    PRIMARY KEY (clip_id, version),
    CONSTRAINT clip_versions_rotations_shape_check CHECK (
        array_ndims(rotations) = 3 AND array_length(rotations, 1) = n_frames AND array_length(rotations, 3) = 4),
    CONSTRAINT clip_versions_translations_shape_check CHECK (translations IS NULL OR (
        array_ndims(translations) = 3 AND array_length(translations, 1) = n_frames AND array_length(translations, 3) = 3)),
    CONSTRAINT clip_versions_rotations_unit_check CHECK (modb.unit_quaternions_ok(rotations, 1e-5)),
    CONSTRAINT clip_versions_translations_finite_check CHECK (translations IS NULL OR modb.finite_ok(translations)),
    CONSTRAINT clip_versions_meta_check CHECK (modb.annotations_ok(meta, n_frames))
);
COMMENT ON TABLE modb.clip_versions IS
    'Immutable versions of a clip''s motion (only meta may change); re-loading a changed file or editing adds a version';
COMMENT ON COLUMN modb.clip_versions.rotations IS
    'real[n_frames][n_joints][4]: per frame and joint a unit quaternion (w, x, y, z), w >= 0, relative to the parent, joints in skeleton order';
COMMENT ON COLUMN modb.clip_versions.translations IS
    'real[n_frames][n_translated][3]: local translation in metres of each joint with position channels (skeleton hierarchy->translated), replacing its offset; NULL when none';
COMMENT ON COLUMN modb.clip_versions.source_sha256 IS 'sha256 of the source file; loading an unchanged file again stores nothing';
COMMENT ON COLUMN modb.clip_versions.load_params IS 'How the file was read: units rule, metres per unit, frame time';
COMMENT ON COLUMN modb.clip_versions.meta IS
    'Editable: {"annotations": [{"name", "start", "end"} (frames, 0-based, inclusive)], "tags": [...], ...}';

CREATE TABLE modb.models (
    id          bigserial PRIMARY KEY,
    name        text NOT NULL,
    kind        text NOT NULL,
    skeleton_id bigint REFERENCES modb.skeletons (id),
    data        jsonb NOT NULL,
    meta        jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at  timestamptz NOT NULL DEFAULT now(),
    UNIQUE (name, kind)
);
COMMENT ON TABLE modb.models IS 'Statistical motion models (jsonb), by name and kind';

CREATE TABLE modb.graphs (
    id          bigserial PRIMARY KEY,
    name        text NOT NULL,
    kind        text NOT NULL,
    skeleton_id bigint REFERENCES modb.skeletons (id),
    data        jsonb NOT NULL,
    meta        jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at  timestamptz NOT NULL DEFAULT now(),
    UNIQUE (name, kind)
);
COMMENT ON TABLE modb.graphs IS 'Motion graphs (jsonb), by name and kind';

CREATE INDEX clip_versions_skeleton_idx ON modb.clip_versions (skeleton_id);
CREATE INDEX clip_versions_sha256_idx ON modb.clip_versions (source_sha256);
CREATE INDEX clips_collection_idx ON modb.clips (collection_id);

-- pg_dump keeps the data of extension tables only when they are registered here;
-- the sequences too, so ids issued after a restore do not collide.
SELECT pg_catalog.pg_extension_config_dump('modb.collections', '');
SELECT pg_catalog.pg_extension_config_dump('modb.collections_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.skeletons', '');
SELECT pg_catalog.pg_extension_config_dump('modb.skeletons_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clips', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clips_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clip_versions', '');
SELECT pg_catalog.pg_extension_config_dump('modb.models', '');
SELECT pg_catalog.pg_extension_config_dump('modb.models_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.graphs', '');
SELECT pg_catalog.pg_extension_config_dump('modb.graphs_id_seq', '');
