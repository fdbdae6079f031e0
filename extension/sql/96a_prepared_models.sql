-- Motion models prepared once per server process (0.29.0, issue 62): modb.synthesize_from_models reads,
-- parses and prepares a graph's models (3-5 MB of JSON each) the first time a backend needs them and keeps
-- them for its next calls, read again only when a model's row changed (modb_kernel.prepared_models). What
-- this session's backend holds, and how often it read each, is here to see.

CREATE OR REPLACE FUNCTION modb.prepared_models()
RETURNS TABLE (model_id bigint, name text, version int, reads int, served int, megabytes float8)
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE  -- this process's memory: not a parallel worker's
AS $py$
#@modb_kernel prepared_models
return kernel.prepared_models.PREPARED.rows()
$py$;
COMMENT ON FUNCTION modb.prepared_models() IS
    'The motion models this session''s server process holds prepared for modb.synthesize_from_models (read once per process, read again when the model''s row or its skeleton''s changed, at most 32 models and 64 MB of their JSON, the least recently used dropped first): per model its id, name and version, how often this process read its documents (reads), how many calls it served without reading them (served), and its documents'' size as JSON text (MB)';
REVOKE EXECUTE ON FUNCTION modb.prepared_models() FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.prepared_models() TO modb_reader;
