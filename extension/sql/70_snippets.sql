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
#@modb_kernel
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
    """SELECT v.clip_id, v.version, v.fps, v.n_frames, s.id AS skeleton_id, s.hierarchy,
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
# Frames are read a slice at a time (and the clip cut chunk by chunk): memory stays bounded whatever
# the clip's length, and no jsonb argument approaches its size limit.
read_frames = plpy.prepare(
    "SELECT rotations[$3:$4] AS rotations, translations[$3:$4] AS translations "
    "FROM modb.clip_versions WHERE clip_id = $1 AND version = $2", ["bigint", "int", "int", "int"])
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

def flat_real(a):
    # Rounded to float4 here: a value below float4's range (a resampled clip had 3.8e-51) is then 0, where
    # the real[] input refused it. Normal values round as the input would.
    return np.asarray(a, dtype=np.float32).astype(np.float64).reshape(len(a), -1).tolist()

def frames(row, lo, hi):
    """Rotations and translations (None when no joint has position channels) of frames lo..hi-1."""
    r = plpy.execute(read_frames, [row["clip_id"], row["version"], lo + 1, hi])[0]
    return (np.asarray(r["rotations"], dtype=np.float64),
            None if r["translations"] is None else np.asarray(r["translations"], dtype=np.float64))

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
    n_frames = row["n_frames"]
    firsts, length, stride = T.windows(n_frames, row["fps"], window_seconds, stride_seconds)
    slow = T.snippet_rate_error(row["fps"], window_seconds)
    if slow:  # checked here, not left to snippet_sources' constraint, to say what to do
        plpy.error(f'clip {row["clip_id"]} ({row["name"]}) cannot be cut into snippets: {slow}',
                   hint="resample the clip (modb resample, or an edit script's resample) or give a longer window_seconds",
                   sqlstate="22023")
    # A new version replaces the old versions' snippets, and keeps their mirror images if they had them.
    old_flags = {r["mirrored"] for r in plpy.execute(drop_old, [row["clip_id"], row["version"]])}
    existing = {r["mirrored"] for r in plpy.execute(built, [row["clip_id"], row["version"]])}
    parents = [j["parent"] for j in h["joints"]]
    offsets = [j["offset"] for j in h["joints"]]
    for flag in sorted(({bool(mirrored)} | old_flags) - existing):
        plpy.execute(add_source, [row["clip_id"], row["version"], length, stride, flag])
        if len(firsts) == 0:
            continue  # shorter than one snippet: recorded as built, nothing to add
        if flag:
            pairs = json.loads(row["mirror_pairs"])
            if not pairs:
                plpy.error(f'clip {row["clip_id"]} ({row["name"]}): skeleton {row["skeleton_id"]} has no mirror pairs',
                           hint="fill modb.skeletons.mirror_pairs with its [left, right] joints")
            partner = kernel.mirror.partner_index(names, pairs)
            statistics = kernel.mirror.ClipStatistics(parents, offsets, partner, h["translated"])
            for lo in range(0, n_frames, T.CHUNK_FRAMES):
                statistics.add(*frames(row, lo, min(n_frames, lo + T.CHUNK_FRAMES)))
            reflections = statistics.reflections([j["end_site"] for j in h["joints"]])
        ids = {}  # terminator id by frame, for the snippets still to come
        for lo, hi, starts in T.chunks(n_frames, row["fps"], firsts, length):
            rotations, translations = frames(row, lo, hi)
            if flag:
                rotations, translations = kernel.mirror.reflect(reflections, parents, partner, rotations,
                                                                translations, h["translated"])
            terms = T.compute(parents, offsets, rotations, translations, h["translated"], std, row["fps"])
            ids = {f: i for f, i in ids.items() if f >= starts[0]}
            wanted = sorted((set(starts.tolist()) | set((starts + length - 1).tolist())) - set(ids))
            local = [f - lo for f in wanted]
            pick = {k: flat_real(terms[k][local]) for k in ("positions", "rotations", "velocities", "angular_velocities")}
            pick["features"] = flat(terms["features"][local])
            configuration = terms["configuration"][local].astype(np.float32).astype(np.float64).tolist()
            records = [{"frame": f, "heading": float(terms["heading"][f - lo]),
                        "pelvis_height": float(np.float32(terms["pelvis_height"][f - lo])),
                        "positions": pick["positions"][i], "rotations": pick["rotations"][i],
                        "velocities": pick["velocities"][i], "angular_velocities": pick["angular_velocities"][i],
                        "configuration": configuration[i], "features": pick["features"][i]}
                       for i, f in enumerate(wanted)]
            ids.update({r["frame"]: r["id"] for r in plpy.execute(add_terminators, [row["clip_id"], row["version"],
                                                                                   json.dumps(records), flag])})
            snippets = []
            for first in starts.tolist():
                last = first + length - 1
                translation, turn, rotation = T.net_motion(terms, first - lo, last - lo)
                snippets.append({"first_frame": first, "begin_terminator": ids[first], "end_terminator": ids[last],
                                 "net_translation": translation.tolist(), "net_heading": float(turn),
                                 "net_rotation": rotation.tolist()})
            plpy.execute(add_snippets, [row["clip_id"], row["version"], length, row["collection_id"], row["pose_key"],
                                        row["fps"], json.dumps(snippets), flag])
            added += len(snippets)
plpy.execute("SELECT modb.fill_futures()")  # after every clip's snippets exist: futures chain through them
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
