-- Checks of motion model documents (0.26.0): every row written to modb.models of kind motion_primitive
-- must be a model that can be sampled, whoever writes it (a build, an import, REST, plain SQL), and its
-- acceleration tree must be drawn from its own mixture. As 99_stored_document_checks.sql: a trigger,
-- in words, on what a statement writes; the upgrade to 0.26.0 repaired the rows stored before.

CREATE OR REPLACE FUNCTION modb.model_document_problems(data jsonb)
RETURNS text[]
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
#@modb_kernel model_check
import json
if len(data) > kernel.model_check.MAX_DOCUMENT_BYTES:
    return [f"the document has {len(data) / 2**20:,.1f} MB of JSON, more than the "
            f"{kernel.model_check.MAX_DOCUMENT_BYTES / 2**20:,.0f} MB a model may have"]
return kernel.model_check.problems(json.loads(data))
$py$;
COMMENT ON FUNCTION modb.model_document_problems(jsonb) IS
    'Why a motion model document (modb.models data of kind motion_primitive) cannot be sampled: its size, a missing or malformed field, a number not finite, fps out of 1..1000, weights not summing to 1, a covariance not positive definite; empty when it can';

-- The acceleration tree in a model's meta is drawn from its data's mixture: stamped with that mixture's
-- md5 when it is written, so that a new version (a replace, an import) never carries a tree of other data.
CREATE FUNCTION modb.model_mixture_md5(data jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN md5((data->'mixture')::text);
COMMENT ON FUNCTION modb.model_mixture_md5(jsonb) IS
    'The md5 of a model document''s mixture (as jsonb text): the stamp its acceleration tree (meta.tree.mixture_md5) must carry';

CREATE FUNCTION modb.models_check_documents()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    problems text[];
BEGIN
    IF octet_length(NEW.meta::text) > 32 * 1024 * 1024 THEN
        RAISE EXCEPTION 'model "%": its meta has % MB of JSON, more than the 32 MB it may have', NEW.name,
                        round(octet_length(NEW.meta::text) / 1048576.0, 1)
            USING ERRCODE = 'check_violation', HINT = 'keep notes short; the acceleration tree of 10,000 samples takes about 5 MB';
    END IF;
    IF NEW.kind <> 'motion_primitive' THEN
        IF octet_length(NEW.data::text) > 16 * 1024 * 1024 THEN
            RAISE EXCEPTION 'model "%": its data has % MB of JSON, more than the 16 MB a model may have', NEW.name,
                            round(octet_length(NEW.data::text) / 1048576.0, 1)
                USING ERRCODE = 'check_violation';
        END IF;
        RETURN NEW;
    END IF;
    IF TG_OP = 'INSERT' THEN
        problems := modb.model_document_problems(NEW.data);
        IF cardinality(problems) > 0 THEN
            RAISE EXCEPTION 'motion model "%" is not stored: %', NEW.name, array_to_string(problems, '; ')
                USING ERRCODE = 'check_violation',
                      HINT = '`modb model build` makes a model of a collection''s steps; `modb model export` writes one '
                             'that imports';
        END IF;
    END IF;
    IF NEW.meta ? 'tree' AND (TG_OP = 'INSERT' OR NEW.meta->'tree' IS DISTINCT FROM OLD.meta->'tree') THEN
        IF TG_OP = 'UPDATE' AND NOT NEW.meta->'tree' ? 'mixture_md5' THEN  -- a tree written now: stamp it
            NEW.meta := jsonb_set(NEW.meta, '{tree,mixture_md5}', to_jsonb(modb.model_mixture_md5(NEW.data)));
        ELSIF NEW.meta->'tree'->>'mixture_md5' IS DISTINCT FROM modb.model_mixture_md5(NEW.data) THEN
            RAISE EXCEPTION 'motion model "%": the acceleration tree in its meta was drawn from another mixture', NEW.name
                USING ERRCODE = 'check_violation',
                      HINT = format('store it without meta.tree, then `modb model tree %s` draws one from its own mixture',
                                    NEW.name);
        END IF;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.models_check_documents() IS
    'Trigger: a motion model is stored only when it can be sampled (modb.model_document_problems), data at most 16 MB and meta 32 MB of JSON, and an acceleration tree only with the mixture it was drawn from (a tree written by an UPDATE is stamped with it)';
CREATE TRIGGER models_check_documents BEFORE INSERT OR UPDATE OF meta ON modb.models
    FOR EACH ROW EXECUTE FUNCTION modb.models_check_documents();

-- A graph of models names its models by id: a version a graph names is not deleted from under it.
CREATE FUNCTION modb.models_keep_what_graphs_name()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    graphs text;
BEGIN
    SELECT CASE count(*) WHEN 1 THEN 'the graph of models ' ELSE 'the graphs of models ' END
           || string_agg(format('"%s"', g.name), ', ' ORDER BY g.name)
           || CASE count(*) WHEN 1 THEN ' names it' ELSE ' name it' END INTO graphs
      FROM modb.graphs g
     WHERE g.kind = 'models'
       AND EXISTS (SELECT FROM jsonb_each(g.data->'nodes') n WHERE n.value->>'model_id' = OLD.id::text);
    IF graphs IS NOT NULL THEN  -- (string_agg of no rows is NULL)
        RAISE EXCEPTION 'motion model "%" version % is not deleted: %', OLD.name, OLD.version, graphs
            USING ERRCODE = 'dependent_objects_still_exist',
                  HINT = format('delete those graphs first (modb model graph delete NAME), or rebuild them on other '
                                'versions: modb model graph NAME --collection C --model %s', OLD.name);
    END IF;
    RETURN OLD;
END
$$;
COMMENT ON FUNCTION modb.models_keep_what_graphs_name() IS
    'Trigger: a motion model version that a graph of models names is not deleted; the refusal names the graphs and how to rebuild them';
CREATE TRIGGER models_keep_what_graphs_name BEFORE DELETE ON modb.models
    FOR EACH ROW EXECUTE FUNCTION modb.models_keep_what_graphs_name();
