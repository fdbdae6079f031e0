-- What a listing of motion models reads (0.26.0): a few columns the database derives from each version
-- as it is written, and the processed-data rows it was built from as rows of their own, so that listing
-- or showing versions and saying which are stale reads no model document (a version's data is about
-- 0.7 MB, its acceleration tree 4.5 MB) and no frames: each listed version costs an index lookup per
-- example, however many versions and processed rows there are.

ALTER TABLE modb.models
    ADD COLUMN primitive text GENERATED ALWAYS AS (data->>'primitive') STORED,
    ADD COLUMN examples int GENERATED ALWAYS AS (
        CASE WHEN jsonb_typeof(data->'inputs') = 'array' THEN jsonb_array_length(data->'inputs') END) STORED,
    ADD COLUMN components int GENERATED ALWAYS AS (
        CASE WHEN jsonb_typeof(data->'mixture'->'weights') = 'array'
             THEN jsonb_array_length(data->'mixture'->'weights') END) STORED,
    ADD COLUMN has_tree boolean GENERATED ALWAYS AS (meta ? 'tree') STORED;
COMMENT ON COLUMN modb.models.primitive IS 'The primitive a motion model models (its data''s "primitive"), kept for listings';
COMMENT ON COLUMN modb.models.examples IS 'How many processed-data rows it was built from (its data''s "inputs"), kept for listings';
COMMENT ON COLUMN modb.models.components IS 'How many Gaussians its mixture has, kept for listings';
COMMENT ON COLUMN modb.models.has_tree IS 'Whether its meta holds an acceleration tree, kept for listings';

-- Derived from modb.models as it is written (a restore rebuilds it), so not dumped of its own.
CREATE TABLE modb.model_inputs (
    model_id     bigint NOT NULL REFERENCES modb.models (id) ON DELETE CASCADE,
    processed_id bigint NOT NULL,
    PRIMARY KEY (model_id, processed_id)
);
CREATE INDEX model_inputs_processed_idx ON modb.model_inputs (processed_id);
COMMENT ON TABLE modb.model_inputs IS
    'The processed-data rows (modb.processed_data ids) each model version was built from: its data''s "inputs", kept by a trigger so that modb.model_status reads no document';
GRANT SELECT ON modb.model_inputs TO modb_reader;

-- SECURITY DEFINER (plain PL/pgSQL, a fixed search_path): the rows are the database's to keep, so no
-- loader writes them by hand.
CREATE FUNCTION modb.models_keep_inputs()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE SECURITY DEFINER SET search_path = pg_catalog, pg_temp
AS $$
BEGIN
    IF jsonb_typeof(NEW.data->'inputs') = 'array' THEN
        INSERT INTO modb.model_inputs (model_id, processed_id)
        SELECT DISTINCT NEW.id, (i->>'id')::bigint
          FROM jsonb_array_elements(NEW.data->'inputs') i
         WHERE jsonb_typeof(i->'id') = 'number';
    END IF;
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.models_keep_inputs() IS
    'Trigger: a model version''s "inputs" (processed-data ids) kept in modb.model_inputs as it is stored';
CREATE TRIGGER models_keep_inputs AFTER INSERT ON modb.models
    FOR EACH ROW EXECUTE FUNCTION modb.models_keep_inputs();

-- No window function: a WHERE on the view (one version, one name) reaches the table, so only the versions
-- asked for are judged.
CREATE OR REPLACE VIEW modb.model_status AS
SELECT m.id, m.name, m.kind, m.version,
       m.version = (SELECT max(l.version) FROM modb.models l WHERE l.name = m.name AND l.kind = m.kind) AS latest,
       modb.collection_path(m.collection_id) AS collection, m.primitive, m.skeleton_id, m.created_at,
       CASE WHEN m.examples IS NULL THEN NULL
            WHEN m.collection_id IS NULL THEN 'its collection was deleted'
            WHEN EXISTS (SELECT FROM modb.model_inputs i
                          WHERE i.model_id = m.id
                            AND NOT EXISTS (SELECT FROM modb.processed_data p WHERE p.id = i.processed_id))
                 THEN 'processed data it was built from was deleted or aligned again'
            WHEN EXISTS (SELECT FROM modb.processed_data p
                          WHERE p.collection_id = m.collection_id AND p.primitive = m.primitive
                            AND NOT EXISTS (SELECT FROM modb.model_inputs i
                                             WHERE i.model_id = m.id AND i.processed_id = p.id))
                 THEN 'the primitive has processed data it was not built from'
            ELSE (SELECT 'processed data it was built from is stale: ' || min(s.stale)
                    FROM modb.model_inputs i JOIN modb.processed_data_status s ON s.id = i.processed_id
                   WHERE i.model_id = m.id AND s.stale IS NOT NULL)
       END AS stale
  FROM modb.models m;
COMMENT ON VIEW modb.model_status IS
    'Each model version without its data: whether it is its name''s latest, what it was built from, and why it is stale (NULL: current): its collection was deleted, or the processed data it was built from was deleted, aligned again, joined by new examples, or is stale itself';
GRANT SELECT ON modb.model_status TO modb_reader;
