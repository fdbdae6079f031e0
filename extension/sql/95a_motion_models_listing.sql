-- What a listing of motion models reads (0.26.0): a few columns the database derives from each version
-- as it is written, and the processed-data rows it was built from as rows of their own, so that listing
-- or showing versions and saying which are stale reads no model document (a version's data is about
-- 0.7 MB, its acceleration tree 4.5 MB) and no frames: each listed version costs an index lookup per
-- example, however many versions and processed rows there are.

CREATE FUNCTION modb.tree_shape(meta jsonb)
RETURNS jsonb
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN (WITH RECURSIVE node(body, depth) AS (
            SELECT meta->'tree'->'root', 1 WHERE jsonb_typeof(meta->'tree'->'root') = 'object'
            UNION ALL
            SELECT c, n.depth + 1
              FROM node n, jsonb_array_elements(CASE WHEN jsonb_typeof(n.body->'children') = 'array'
                                                     THEN n.body->'children' ELSE '[]' END) c)
        SELECT jsonb_build_object('nodes', count(*), 'leaves', count(*) FILTER (WHERE body ? 'samples'),
                                  'depth', max(depth),
                                  'samples', coalesce(sum(CASE WHEN jsonb_typeof(body->'samples') = 'array'
                                                               THEN jsonb_array_length(body->'samples') END), 0))
          FROM node HAVING count(*) > 0);
COMMENT ON FUNCTION modb.tree_shape(jsonb) IS
    'The shape of the acceleration tree in a model''s meta: {"nodes", "leaves", "depth", "samples" (held by the leaves)}; NULL without one';

ALTER TABLE modb.models
    ADD COLUMN primitive text GENERATED ALWAYS AS (data->>'primitive') STORED,
    ADD COLUMN examples int GENERATED ALWAYS AS (
        CASE WHEN jsonb_typeof(data->'inputs') = 'array' THEN jsonb_array_length(data->'inputs') END) STORED,
    ADD COLUMN components int GENERATED ALWAYS AS (
        CASE WHEN jsonb_typeof(data->'mixture'->'weights') = 'array'
             THEN jsonb_array_length(data->'mixture'->'weights') END) STORED,
    ADD COLUMN has_tree boolean GENERATED ALWAYS AS (meta ? 'tree') STORED,
    ADD COLUMN tree_shape jsonb GENERATED ALWAYS AS (modb.tree_shape(meta)) STORED;
COMMENT ON COLUMN modb.models.primitive IS 'The primitive a motion model models (its data''s "primitive"), kept for listings';
COMMENT ON COLUMN modb.models.examples IS 'How many processed-data rows it was built from (its data''s "inputs"), kept for listings';
COMMENT ON COLUMN modb.models.components IS 'How many Gaussians its mixture has, kept for listings';
COMMENT ON COLUMN modb.models.has_tree IS 'Whether its meta holds an acceleration tree, kept for listings';
COMMENT ON COLUMN modb.models.tree_shape IS 'Its acceleration tree''s shape (modb.tree_shape), kept for `modb model show`';

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

-- Judged in three passes over small rows, each once however many versions are listed: each processed row's
-- staleness, what each version's inputs have become, and how many processed rows each primitive has. No
-- window function: a WHERE on the view (one version, one name) reaches the models table.
CREATE OR REPLACE VIEW modb.model_status AS
WITH processed AS MATERIALIZED (
    SELECT p.id, p.collection_id, p.primitive,
           CASE WHEN c.version IS DISTINCT FROM p.version THEN 'the clip has a newer version'
                WHEN NOT EXISTS (SELECT FROM jsonb_array_elements(coalesce(v.meta->'annotations', '[]')) a
                                  WHERE a = p.segment) THEN 'its segment changed or is gone'
           END AS stale
      FROM modb.processed_data p
      LEFT JOIN modb.current_clips c ON c.clip_id = p.clip_id
      LEFT JOIN modb.clip_versions v ON v.clip_id = p.clip_id AND v.version = p.version
), inputs AS MATERIALIZED (
    SELECT i.model_id, count(*) FILTER (WHERE p.id IS NULL) AS gone, min(p.stale) AS stale,
           count(*) FILTER (WHERE p.collection_id = m.collection_id AND p.primitive = m.primitive) AS own
      FROM modb.model_inputs i
      JOIN modb.models m ON m.id = i.model_id
      LEFT JOIN processed p ON p.id = i.processed_id
     GROUP BY i.model_id
), available AS MATERIALIZED (
    SELECT p.collection_id, p.primitive, count(*) AS n FROM processed p GROUP BY 1, 2
)
SELECT m.id, m.name, m.kind, m.version,
       m.version = (SELECT max(l.version) FROM modb.models l WHERE l.name = m.name AND l.kind = m.kind) AS latest,
       modb.collection_path(m.collection_id) AS collection, m.primitive, m.skeleton_id, m.created_at,
       CASE WHEN m.examples IS NULL THEN NULL
            WHEN m.collection_id IS NULL THEN 'its collection was deleted'
            WHEN i.gone > 0 THEN 'processed data it was built from was deleted or aligned again'
            WHEN coalesce(a.n, 0) > coalesce(i.own, 0) THEN 'the primitive has processed data it was not built from'
            ELSE 'processed data it was built from is stale: ' || i.stale
       END AS stale
  FROM modb.models m
  LEFT JOIN inputs i ON i.model_id = m.id
  LEFT JOIN available a ON a.collection_id = m.collection_id AND a.primitive = m.primitive;
COMMENT ON VIEW modb.model_status IS
    'Each model version without its data: whether it is its name''s latest, what it was built from, and why it is stale (NULL: current): its collection was deleted, or the processed data it was built from was deleted, aligned again, joined by new examples, or is stale itself';
GRANT SELECT ON modb.model_status TO modb_reader;
