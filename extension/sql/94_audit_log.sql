-- What every write through the REST interface did, and under which token. Insert-only: no grant lets a
-- role update or delete a row, and triggers refuse it even to the table's owner (a superuser can still
-- drop them: the log is evidence against mistakes, not against the cluster's administrator).
CREATE TABLE modb.audit_log (
    id         bigserial PRIMARY KEY,
    at         timestamptz NOT NULL DEFAULT clock_timestamp(),
    token_name text NOT NULL,
    db_role    name NOT NULL DEFAULT current_user,
    action     text NOT NULL,
    object     text NOT NULL,
    detail     jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(detail) = 'object')
);
COMMENT ON TABLE modb.audit_log IS
    'One row per write through the REST interface: when, the token''s name, the database role that wrote, the action (e.g. upload, meta), its object (e.g. clip 12 version 2) and details; insert-only';
SELECT pg_catalog.pg_extension_config_dump('modb.audit_log', '');
SELECT pg_catalog.pg_extension_config_dump('modb.audit_log_id_seq', '');

CREATE FUNCTION modb.audit_log_refuse()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    RAISE EXCEPTION 'modb.audit_log is insert-only: its rows cannot be %', lower(TG_OP) || 'd'
        USING ERRCODE = 'insufficient_privilege', HINT = 'the log keeps every write; add a row instead';
END
$$;
COMMENT ON FUNCTION modb.audit_log_refuse() IS 'Trigger function: refuses UPDATE, DELETE and TRUNCATE of modb.audit_log';
CREATE TRIGGER audit_log_insert_only BEFORE UPDATE OR DELETE ON modb.audit_log
    FOR EACH ROW EXECUTE FUNCTION modb.audit_log_refuse();
CREATE TRIGGER audit_log_no_truncate BEFORE TRUNCATE ON modb.audit_log
    FOR EACH STATEMENT EXECUTE FUNCTION modb.audit_log_refuse();

GRANT SELECT ON modb.audit_log TO modb_loader;
GRANT INSERT (token_name, action, object, detail) ON modb.audit_log TO modb_loader;
GRANT USAGE ON SEQUENCE modb.audit_log_id_seq TO modb_loader;
