-- Access tokens for the REST interface (modb serve). A token is shown once, when `modb token create` makes
-- it; only its sha256 is stored (a token is 32 random bytes, so a fast hash is enough: there is nothing to
-- guess). No role but the owner reads the table: the server asks modb.token_grant, which answers for one
-- hash at a time.
CREATE TABLE modb.access_tokens (
    id           bigserial PRIMARY KEY,
    name         text NOT NULL UNIQUE CHECK (name ~ '^[A-Za-z0-9][A-Za-z0-9._@-]{0,62}$'),
    role         text NOT NULL CHECK (role IN ('loader', 'reader')),
    token_sha256 bytea NOT NULL UNIQUE CHECK (length(token_sha256) = 32),
    created_at   timestamptz NOT NULL DEFAULT now(),
    created_by   name NOT NULL DEFAULT current_user,
    revoked_at   timestamptz
);
COMMENT ON TABLE modb.access_tokens IS
    'REST access tokens (modb token create|list|revoke): name, role (loader: writes; reader: reads), the sha256 of the token (the token itself is never stored), when made and revoked';
SELECT pg_catalog.pg_extension_config_dump('modb.access_tokens', '');
SELECT pg_catalog.pg_extension_config_dump('modb.access_tokens_id_seq', '');

CREATE FUNCTION modb.token_grant(token_sha256 bytea)
RETURNS TABLE (name text, role text)
LANGUAGE sql STABLE STRICT PARALLEL SAFE SECURITY DEFINER
SET search_path = pg_catalog, pg_temp
BEGIN ATOMIC
    SELECT t.name, t.role FROM modb.access_tokens t
     WHERE t.token_sha256 = token_grant.token_sha256 AND t.revoked_at IS NULL;
END;
COMMENT ON FUNCTION modb.token_grant(bytea) IS
    'The name and role of the live token with this sha256 (none when unknown or revoked): how the server checks a Bearer token without reading modb.access_tokens';
REVOKE EXECUTE ON FUNCTION modb.token_grant(bytea) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.token_grant(bytea) TO modb_reader;

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
