-- Snippets (~0.5 s windows of real capture), the terminators at their ends, and where they came from.
-- The frames themselves stay in modb.clip_versions: a snippet is a window onto them, never a copy.
-- Below: their tables, the GiST index of their begin features, where each one leads (futures), and
-- modb.build_snippets, which cuts clips into them. Their blocks: 71_snippet_blocks.sql.

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

CREATE INDEX snippets_clip_idx ON modb.snippets (clip_id, version, mirrored, first_frame);
CREATE INDEX snippets_pose_key_idx ON modb.snippets (pose_key, fps);
CREATE INDEX snippets_collection_idx ON modb.snippets (collection_id, id);  -- a collection's snippets (src/candidate_sets.c)
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

-- The GiST index of the feature cube: contrib/cube's support functions with modb's penalty and split
-- (src/cube_gist.c: cube's volume-based ones degenerate in 49 dimensions and the selection's box overlapped
-- most of the index's pages). Every operator of cube's own class, so any cube query can use the index.

CREATE FUNCTION modb.feature_cube_penalty(internal, internal, internal)
RETURNS internal
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_cube_penalty';
COMMENT ON FUNCTION modb.feature_cube_penalty(internal, internal, internal) IS
    'GiST support (modb.cube_feature_ops): the growth of a page''s sum of extents, not of its volume, to take in an entry';

CREATE FUNCTION modb.feature_cube_picksplit(internal, internal)
RETURNS internal
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_cube_picksplit';
COMMENT ON FUNCTION modb.feature_cube_picksplit(internal, internal) IS
    'GiST support (modb.cube_feature_ops): the R*-tree''s split, with sums of extents in place of volumes';

CREATE OPERATOR CLASS modb.cube_feature_ops FOR TYPE cube USING gist AS
    OPERATOR 3 &&,
    OPERATOR 6 =,
    OPERATOR 7 @>,
    OPERATOR 8 <@,
    OPERATOR 15 ~> (cube, int) FOR ORDER BY float_ops,
    OPERATOR 16 <#> (cube, cube) FOR ORDER BY float_ops,
    OPERATOR 17 <-> (cube, cube) FOR ORDER BY float_ops,
    OPERATOR 18 <=> (cube, cube) FOR ORDER BY float_ops,
    FUNCTION 1 g_cube_consistent (internal, cube, smallint, oid, internal),
    FUNCTION 2 g_cube_union (internal, internal),
    FUNCTION 5 modb.feature_cube_penalty (internal, internal, internal),
    FUNCTION 6 modb.feature_cube_picksplit (internal, internal),
    FUNCTION 7 g_cube_same (cube, cube, internal),
    FUNCTION 8 g_cube_distance (internal, cube, smallint, oid, internal);
COMMENT ON OPERATOR CLASS modb.cube_feature_ops USING gist IS
    'GiST for snippet feature cubes: cube''s operators and search, a penalty and split that stay selective in 49 dimensions';

CREATE INDEX snippets_begin_features_idx ON modb.snippets USING gist (begin_features modb.cube_feature_ops);

-- Where a snippet leads: itself and up to two play-on snippets (each starting on the previous one's last
-- frame, in the same clip version and mirror image), composed from their net motions. The objective of
-- select_next_snippet measures this, so that a choice that leads into a turn is seen as turning: a
-- snippet's own 0.5 s says little about where the clip goes (a turn clip's lead-in walks straight).

CREATE FUNCTION modb.fill_futures()
RETURNS bigint
LANGUAGE sql VOLATILE PARALLEL UNSAFE
BEGIN ATOMIC
    WITH chain AS (
        SELECT s.id, s.net_translation AS t0, s.net_heading AS h0,
               a.net_translation AS t1, coalesce(a.net_heading, 0) AS h1,
               b.net_translation AS t2, coalesce(b.net_heading, 0) AS h2
          FROM modb.snippets s
          LEFT JOIN modb.snippets a ON a.clip_id = s.clip_id AND a.version = s.version AND a.mirrored = s.mirrored
                                   AND a.first_frame = s.first_frame + s.n_frames - 1
          LEFT JOIN modb.snippets b ON b.clip_id = a.clip_id AND b.version = a.version AND b.mirrored = a.mirrored
                                   AND b.first_frame = a.first_frame + a.n_frames - 1
         WHERE s.future_translation IS NULL
    ), updated AS (
        UPDATE modb.snippets s
           SET future_translation = ARRAY[
                   c.t0[1] + coalesce(c.t1[1] * cos(c.h0) + c.t1[3] * sin(c.h0), 0)
                           + coalesce(c.t2[1] * cos(c.h0 + c.h1) + c.t2[3] * sin(c.h0 + c.h1), 0),
                   c.t0[2] + coalesce(c.t1[2], 0) + coalesce(c.t2[2], 0),
                   c.t0[3] + coalesce(c.t1[3] * cos(c.h0) - c.t1[1] * sin(c.h0), 0)
                           + coalesce(c.t2[3] * cos(c.h0 + c.h1) - c.t2[1] * sin(c.h0 + c.h1), 0)],
               future_heading = atan2(sin(c.h0 + c.h1 + c.h2), cos(c.h0 + c.h1 + c.h2))
          FROM chain c
         WHERE c.id = s.id
        RETURNING 1)
    SELECT count(*) FROM updated;
END;
COMMENT ON FUNCTION modb.fill_futures() IS
    'Fills future_translation and future_heading of the snippets that lack them (build_snippets calls it); returns how many';
REVOKE EXECUTE ON FUNCTION modb.fill_futures() FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.fill_futures() TO modb_loader;

-- Cutting clips into snippets (the kernel's terminators module computes what they store).
CREATE OR REPLACE FUNCTION modb._build_snippets(collection text DEFAULT NULL, clip bigint DEFAULT NULL,
                                    window_seconds float8 DEFAULT 0.5, stride_seconds float8 DEFAULT 1.0 / 30,
                                    mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel database snippet_cut
D, C = kernel.database, kernel.snippet_cut
db = D.Server(plpy)
try:
    C.check_window(window_seconds, stride_seconds)
    collections = None
    if collection is not None:
        collections = plpy.execute(plpy.prepare("SELECT modb.collection_subtree($1) AS ids", ["text"]),
                                   [collection])[0]["ids"]
        if not collections:
            raise D.StoreError(f'no collection "{collection}"', hint="modb.collection_path(id) names the stored ones")
    added = sum(C.cut(db, row, mirrored, window_seconds, stride_seconds)
                for row in db.rows(C.TO_CUT, [collections, clip, bool(mirrored)]))
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
db.run(C.FILL_FUTURES)  # after every clip's snippets exist: futures chain through them
return added
$py$;
COMMENT ON FUNCTION modb._build_snippets(text, bigint, float8, float8, boolean) IS
    'Internal: what modb.build_snippets runs (PL/Python); call that one, whose errors read without Python''s exception names';

REVOKE EXECUTE ON FUNCTION modb._build_snippets(text, bigint, float8, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._build_snippets(text, bigint, float8, float8, boolean) TO modb_loader;
CREATE FUNCTION modb.build_snippets(collection text DEFAULT NULL, clip bigint DEFAULT NULL,
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
COMMENT ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) IS
    'Cuts the newest version of every clip in scope (a collection''s subtree, one clip, or all) that has no snippets yet into windows of window_seconds starting every stride_seconds, with their terminators; drops the snippets of older versions. mirrored => true adds the clips'' mirror images (through the skeleton''s mirror_pairs) as further sources. Returns the number of snippets added';
REVOKE EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) TO modb_loader;
