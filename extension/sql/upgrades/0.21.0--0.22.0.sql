-- 0.22.0: statistical motion models. modb.models in versions (a collection, a version, the rules of
-- modb.models_version_rules), modb.model_status, modb.sample_motion; processed data with mirrored examples.
-- The other side's examples, mirrored (88_motion_primitives.sql)
ALTER TABLE modb.processed_data ADD COLUMN mirrored boolean NOT NULL DEFAULT false;
COMMENT ON COLUMN modb.processed_data.mirrored IS
    'True: the example is the other side''s segment (right_step for left_step), mirrored through the skeleton''s mirror pairs (0.22.0)';
DROP INDEX modb.processed_data_example_idx;
CREATE UNIQUE INDEX processed_data_example_idx
    ON modb.processed_data (collection_id, primitive, clip_id, version, segment, mirrored);
CREATE OR REPLACE VIEW modb.processed_data_status AS
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
--@include 95_motion_models.sql
