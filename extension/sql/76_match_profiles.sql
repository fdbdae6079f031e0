-- Match profiles: continuity thresholds by name, resolved into a modb.match_plan (78_match_plan_type.sql,
-- 79_match_plan.sql).

CREATE TABLE modb.match_profiles (
    name     text PRIMARY KEY,
    settings jsonb NOT NULL CHECK (jsonb_typeof(settings) = 'object'),
    comment  text,
    shipped  boolean NOT NULL DEFAULT false
);
COMMENT ON TABLE modb.match_profiles IS
    'Continuity thresholds for select_next_snippet, by name; any setting can be overridden per session with SET modb.<knob>';

-- The shipped profiles: 77_match_profiles_shipped.sql (also run by upgrades, so they follow the release).

GRANT SELECT ON modb.match_profiles TO modb_reader;
-- The loader adds profiles and edits its own.
-- No DELETE: a table-level DELETE would also let it LOCK the table every selection reads.
GRANT INSERT (name, settings, comment) ON modb.match_profiles TO modb_loader;
GRANT UPDATE (settings, comment) ON modb.match_profiles TO modb_loader;
-- Shipped profiles are read-only to it: 91_shipped_profiles_guard.sql.

-- The shipped profiles come with every install (and upgrade); pg_dump keeps the ones users add.
SELECT pg_catalog.pg_extension_config_dump('modb.match_profiles', 'WHERE NOT shipped');
COMMENT ON COLUMN modb.match_profiles.shipped IS
    'Installed with the extension (and replaced by its upgrades): add your own profile rather than editing these';
