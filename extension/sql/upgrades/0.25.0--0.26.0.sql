-- 0.26.0: motion model documents checked where they are written, a model a graph names kept, graphs of
-- models checked in linear time and capped, models listed without reading their documents (issue 58).
--@include 95a_motion_models_listing.sql
INSERT INTO modb.model_inputs (model_id, processed_id)
SELECT DISTINCT m.id, (i->>'id')::bigint
  FROM modb.models m, jsonb_array_elements(CASE WHEN jsonb_typeof(m.data->'inputs') = 'array'
                                                THEN m.data->'inputs' ELSE '[]' END) i
 WHERE jsonb_typeof(i->'id') = 'number';
--@include 94_model_graph_problem.sql
--@include 92_model_document_checks.sql

--@functions

-- Models stored before the check: one that cannot be sampled is deleted (it broke every listing, sample
-- and synthesis that met it), its row kept in modb.repaired_rows; a tree whose scores have another number
-- of dimensions than its mixture was drawn from other data and is dropped (kept the same way); every
-- other tree is stamped with its mixture (one of the same dimensions cannot be told from its own).
DO $$
DECLARE
    r record;
BEGIN
    FOR r IN SELECT m.id, m.name, m.version, to_jsonb(m) AS old_row, modb.model_document_problems(m.data) AS problems
               FROM modb.models m WHERE m.kind = 'motion_primitive' ORDER BY m.id LOOP
        IF cardinality(r.problems) > 0 THEN
            INSERT INTO modb.repaired_rows (table_name, row_key, old_value, problem, repaired_by)
            VALUES ('models', r.id::text, r.old_row, array_to_string(r.problems, '; '), '0.26.0');
            DELETE FROM modb.models WHERE id = r.id;
            RAISE WARNING 'motion model "%" version % is deleted: it cannot be sampled (%); its row is in modb.repaired_rows',
                r.name, r.version, array_to_string(r.problems, '; ');
        END IF;
    END LOOP;
    FOR r IN SELECT m.id, m.name, m.version, m.meta
               FROM modb.models m
              WHERE m.kind = 'motion_primitive' AND m.meta ? 'tree'
                AND jsonb_array_length(m.meta->'tree'->'root'->'mean')
                    IS DISTINCT FROM jsonb_array_length(m.data->'mixture'->'means'->0) ORDER BY m.id LOOP
        INSERT INTO modb.repaired_rows (table_name, row_key, old_value, problem, repaired_by)
        VALUES ('models', r.id::text, jsonb_build_object('meta', r.meta),
                'its acceleration tree was drawn from another mixture', '0.26.0');
        UPDATE modb.models SET meta = meta - 'tree' WHERE id = r.id;
        RAISE WARNING 'motion model "%" version %: its acceleration tree was drawn from another mixture and is dropped: `modb model tree %` draws one',
            r.name, r.version, r.name;
    END LOOP;
    UPDATE modb.models SET meta = jsonb_set(meta, '{tree,mixture_md5}', to_jsonb(modb.model_mixture_md5(data)))
     WHERE kind = 'motion_primitive' AND meta ? 'tree';
END
$$;
