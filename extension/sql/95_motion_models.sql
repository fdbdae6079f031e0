-- Statistical motion models (0.22.0): a primitive's processed data reduced by functional PCA with a
-- Gaussian mixture on the scores (built by the client: modb model build), kept in versions in modb.models,
-- sampled here by the kernel (motion_model.py, model_samples.py) with Debian's numpy and scipy.

-- A model belongs to a collection and a skeleton and has versions: a rebuild (or a replace by any writer)
-- is a new row, the old kept; only meta (the acceleration tree, notes) changes in place.
ALTER TABLE modb.models
    ADD COLUMN collection_id bigint REFERENCES modb.collections (id) ON DELETE SET NULL,
    ADD COLUMN version int NOT NULL DEFAULT 1 CHECK (version > 0),
    DROP CONSTRAINT models_name_kind_key,
    ADD CONSTRAINT models_name_kind_version_key UNIQUE (name, kind, version);
ALTER TABLE modb.models ALTER COLUMN version DROP DEFAULT;
COMMENT ON TABLE modb.models IS
    'Statistical motion models (jsonb) by name, kind and version: a new version is a new row, the old kept; only meta and the collection (NULL once deleted) change';
COMMENT ON COLUMN modb.models.version IS 'The version, 1 up per name and kind; given by the server when left out';
COMMENT ON COLUMN modb.models.collection_id IS 'The collection it was built from; NULL once that is deleted (the model is then stale)';
CREATE INDEX models_collection_idx ON modb.models (collection_id);

CREATE FUNCTION modb.models_version_rules()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF TG_OP = 'INSERT' THEN
        -- one writer at a time per name and kind: two rebuilds get two versions, not a duplicate key
        PERFORM pg_advisory_xact_lock(hashtext('modb model'), hashtext(NEW.kind || '/' || NEW.name));
        IF NEW.version IS NULL THEN
            SELECT coalesce(max(m.version), 0) + 1 INTO NEW.version
              FROM modb.models m WHERE m.name = NEW.name AND m.kind = NEW.kind;
        END IF;
        RETURN NEW;
    END IF;
    IF (NEW.name, NEW.kind, NEW.version, NEW.data, NEW.skeleton_id, NEW.created_at)
       IS DISTINCT FROM (OLD.name, OLD.kind, OLD.version, OLD.data, OLD.skeleton_id, OLD.created_at) THEN
        RAISE EXCEPTION 'model % (% version %) does not change: only its meta may', OLD.id, OLD.name, OLD.version
            USING ERRCODE = '55000', HINT = 'store the change as a new version (an INSERT without a version)';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.models_version_rules() IS
    'Trigger of modb.models: gives an inserted row without a version the next one, and refuses changes to a version other than its meta and collection';
CREATE TRIGGER models_version_rules BEFORE INSERT OR UPDATE ON modb.models
    FOR EACH ROW EXECUTE FUNCTION modb.models_version_rules();


CREATE OR REPLACE FUNCTION modb._sample_motion(model text, n int, seed int, version int)
RETURNS TABLE (sample int, fps float8, n_frames int, rotations real[], translations real[])
LANGUAGE plpython3u STABLE PARALLEL UNSAFE  -- plpy.execute opens a subtransaction: not in a parallel worker
AS $py$
#@modb_kernel database model_samples
D = kernel.database
try:
    return kernel.model_samples.sample_motion(D.Server(plpy), model, n, seed, version)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
$py$;
COMMENT ON FUNCTION modb._sample_motion(text, int, int, int) IS
    'Internal: what modb.sample_motion runs (PL/Python); call that one, whose errors read without Python''s exception names';
CREATE FUNCTION modb.sample_motion(model text, n int, seed int, version int DEFAULT NULL)
RETURNS TABLE (sample int, fps float8, n_frames int, rotations real[], translations real[])
LANGUAGE plpgsql STABLE PARALLEL UNSAFE  -- the EXCEPTION block is a subtransaction: not in a parallel worker
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._sample_motion(model, n, seed, version);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.sample_motion(text, int, int, int) IS
    'n motions (1 to 1000) drawn with the seed (>= 0) from the motion model named model (its latest version, or the one given): frames as clips keep them (rotations real[n_frames][n_joints][4], w first, relative to the parent; translations real[n_frames][n_translated][3] in metres, NULL when none), each starting with the pelvis above the origin, facing +Z. The same model, n and seed give the same motions';
REVOKE EXECUTE ON FUNCTION modb._sample_motion(text, int, int, int) FROM PUBLIC;
REVOKE EXECUTE ON FUNCTION modb.sample_motion(text, int, int, int) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._sample_motion(text, int, int, int) TO modb_reader;
GRANT EXECUTE ON FUNCTION modb.sample_motion(text, int, int, int) TO modb_reader;
