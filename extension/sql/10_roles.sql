-- Roles are cluster-wide, so they are created only when missing and outlive DROP EXTENSION.
DO $$
BEGIN
    IF NOT EXISTS (SELECT FROM pg_catalog.pg_roles WHERE rolname = 'modb_reader') THEN
        CREATE ROLE modb_reader NOLOGIN;
        COMMENT ON ROLE modb_reader IS 'MoDB: read motion data (and, later, select snippets)';
    END IF;
    IF NOT EXISTS (SELECT FROM pg_catalog.pg_roles WHERE rolname = 'modb_loader') THEN
        CREATE ROLE modb_loader NOLOGIN;
        COMMENT ON ROLE modb_loader IS 'MoDB: load and edit motion data (includes modb_reader)';
    END IF;
    IF NOT pg_catalog.pg_has_role('modb_loader', 'modb_reader', 'MEMBER') THEN
        GRANT modb_reader TO modb_loader;
    END IF;
END
$$;
