-- Motion primitives (0.21.0): steps found from foot contacts and written as annotation segments, and a
-- primitive's examples aligned in time to a reference example, kept as processed data (the input of
-- statistical motion models). The kernel does the work (steps.py, primitives.py and step_annotations.py; align.py and
-- processed.py), here and in job workers.

CREATE OR REPLACE FUNCTION modb._annotate_steps(clip bigint)
RETURNS TABLE (version int, name text, start_frame int, end_frame int, keyframes int[])
LANGUAGE plpython3u VOLATILE STRICT PARALLEL UNSAFE
AS $py$
#@modb_kernel database step_annotations
D = kernel.database
try:
    version, made = kernel.step_annotations.annotate(D.Server(plpy), clip)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
return [(version, s["name"], s["start"], s["end"], s["keyframes"]) for s in made]
$py$;
COMMENT ON FUNCTION modb._annotate_steps(bigint) IS
    'Internal: what modb.annotate_steps runs (PL/Python); call that one, whose errors read without Python''s exception names';
REVOKE EXECUTE ON FUNCTION modb._annotate_steps(bigint) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._annotate_steps(bigint) TO modb_loader;
CREATE FUNCTION modb.annotate_steps(clip bigint)
RETURNS TABLE (version int, name text, start_frame int, end_frame int, keyframes int[])
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._annotate_steps(clip);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.annotate_steps(bigint) IS
    'Finds the primitives of the clip''s current version from its feet''s contacts (FK ankles and toes: slower than half a leg length a second and within a tenth of one of the ground) and writes them as annotation segments marked "auto" with their keyframes: left_step (from a right foot''s touchdown to the left''s next one) and right_step; left_turning_step / right_turning_step over the same frames where the step turns more than 20 degrees; left_start / right_start (standing to the first touchdown, named by the foot that moves first), left_stop / right_stop (the last swing to standing, named by the foot that moves last) and idle (standing still at least 0.5 s, in pieces of about 1 s). Replaces the version''s automatic segments and keeps every other. Returns the segments written';
REVOKE EXECUTE ON FUNCTION modb.annotate_steps(bigint) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.annotate_steps(bigint) TO modb_loader;

-- Processed data: one row per example of a primitive in a collection, aligned to the reference.
CREATE TABLE modb.processed_data (
    id            bigserial PRIMARY KEY,
    collection_id bigint NOT NULL REFERENCES modb.collections (id) ON DELETE CASCADE,
    primitive     text NOT NULL CHECK (primitive ~ '^[^[:cntrl:],!:]{1,64}$'),
    clip_id       bigint NOT NULL,
    version       int NOT NULL,
    segment       jsonb NOT NULL CHECK (jsonb_typeof(segment) = 'object'),
    reference     boolean NOT NULL,
    n_frames      int NOT NULL CHECK (n_frames > 0),
    rotations     real[] NOT NULL,
    translations  real[],
    time_function float8[] NOT NULL,
    sections      int[] NOT NULL,
    cost          float8 NOT NULL,
    settings      jsonb NOT NULL,
    created_at    timestamptz NOT NULL DEFAULT now(),
    mirrored      boolean NOT NULL DEFAULT false,
    FOREIGN KEY (clip_id, version) REFERENCES modb.clip_versions (clip_id, version) ON DELETE CASCADE,
    CONSTRAINT processed_data_shape_check CHECK (
        array_ndims(rotations) = 3 AND array_length(rotations, 1) = n_frames AND array_length(rotations, 3) = 4
        AND cardinality(time_function) = n_frames
        AND (translations IS NULL OR (array_ndims(translations) = 3 AND array_length(translations, 1) = n_frames)))
);
CREATE UNIQUE INDEX processed_data_example_idx
    ON modb.processed_data (collection_id, primitive, clip_id, version, segment, mirrored);
CREATE UNIQUE INDEX processed_data_reference_idx ON modb.processed_data (collection_id, primitive) WHERE reference;
CREATE INDEX processed_data_clip_idx ON modb.processed_data (clip_id, version);
COMMENT ON TABLE modb.processed_data IS
    'A motion primitive''s examples (annotation segments named primitive in a collection''s clips) aligned in time to one of them, the reference: per example its frames resampled onto the reference''s (n_frames of them), time_function (the example''s frame, from the segment''s start, for each), sections (the reference''s keyframes, from its start), the warp''s cost, and the version and segment it came from (modb.align_primitive writes it; modb.processed_data_status says which rows are stale)';
COMMENT ON COLUMN modb.processed_data.mirrored IS
    'True: the example is the other side''s segment (right_step for left_step), mirrored through the skeleton''s mirror pairs (0.22.0)';
SELECT pg_catalog.pg_extension_config_dump('modb.processed_data', '');
-- Granted here, not only by 90_privileges.sql, so that an update (which cannot run that again: it would
-- open tables made after it) grants the same.
GRANT SELECT ON modb.processed_data TO modb_reader;
GRANT INSERT, DELETE ON modb.processed_data TO modb_loader;
GRANT USAGE ON SEQUENCE modb.processed_data_id_seq TO modb_loader;
SELECT pg_catalog.pg_extension_config_dump('modb.processed_data_id_seq', '');

CREATE VIEW modb.processed_data_status AS
SELECT p.id, modb.collection_path(p.collection_id) AS collection, p.primitive, p.clip_id, p.version,
       (p.segment->>'start')::int AS start_frame, (p.segment->>'end')::int AS end_frame, p.reference, p.n_frames,
       p.cost, p.created_at,
       CASE WHEN c.version IS DISTINCT FROM p.version THEN 'the clip has a newer version'
            WHEN NOT EXISTS (SELECT FROM jsonb_array_elements(coalesce(v.meta->'annotations', '[]')) a
                              WHERE a = p.segment) THEN 'its segment changed or is gone'
       END AS stale,
       p.mirrored
  FROM modb.processed_data p
  LEFT JOIN modb.current_clips c ON c.clip_id = p.clip_id
  LEFT JOIN modb.clip_versions v ON v.clip_id = p.clip_id AND v.version = p.version;
GRANT SELECT ON modb.processed_data_status TO modb_reader;
COMMENT ON VIEW modb.processed_data_status IS
    'Each processed-data row without its frames, and why it is stale (NULL: it is current): its clip has a newer version, or its segment changed';

CREATE OR REPLACE FUNCTION modb._align_primitive(primitive text, collection text)
RETURNS TABLE (examples int, aligned int, deleted int)
LANGUAGE plpython3u VOLATILE STRICT PARALLEL UNSAFE
AS $py$
#@modb_kernel database processed
D = kernel.database
try:
    return [kernel.processed.align_primitive(D.Server(plpy), primitive, collection)]
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
$py$;
COMMENT ON FUNCTION modb._align_primitive(text, text) IS
    'Internal: what modb.align_primitive runs (PL/Python); call that one, whose errors read without Python''s exception names';
REVOKE EXECUTE ON FUNCTION modb._align_primitive(text, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._align_primitive(text, text) TO modb_loader;
CREATE FUNCTION modb.align_primitive(primitive text, collection text)
RETURNS TABLE (examples int, aligned int, deleted int)
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._align_primitive(primitive, collection);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.align_primitive(text, text) IS
    'Aligns the examples of primitive (the annotation segments of that name in the current versions of the collection''s clips and those below it; at least 5, on one skeleton at one rate) to the one whose length is closest to the mean, by dynamic time warping of FK joint positions between keyframes, into modb.processed_data; keeps rows still current when the reference is unchanged, deletes stale ones, aligns the rest. Returns how many examples, aligned now, deleted';
REVOKE EXECUTE ON FUNCTION modb.align_primitive(text, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.align_primitive(text, text) TO modb_loader;
