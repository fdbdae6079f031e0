-- Match profiles: continuity thresholds by name, resolved into a modb.match_plan (the type below; the
-- functions that resolve it: 79_match_plan.sql).

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
-- Shipped profiles are read-only to it: modb.match_profiles_guard below.

-- The shipped profiles come with every install (and upgrade); pg_dump keeps the ones users add.
SELECT pg_catalog.pg_extension_config_dump('modb.match_profiles', 'WHERE NOT shipped');
COMMENT ON COLUMN modb.match_profiles.shipped IS
    'Installed with the extension (and replaced by its upgrades): add your own profile rather than editing these';

-- A change of the match profiles takes a new generation of the plans sessions cache (69_generations.sql).

CREATE TRIGGER match_profiles_generation AFTER INSERT OR UPDATE OR DELETE OR TRUNCATE ON modb.match_profiles
    FOR EACH STATEMENT EXECUTE FUNCTION modb.next_generation('match_plans');

-- The shipped match profiles (77_match_profiles_shipped.sql) change only with the extension: a loader edits
-- copies of its own.

CREATE FUNCTION modb.match_profiles_guard()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    -- The table's owner (the extension's scripts, a superuser) replaces shipped profiles on update.
    IF OLD.shipped AND NOT pg_catalog.pg_has_role(
            current_user, (SELECT relowner FROM pg_catalog.pg_class WHERE oid = TG_RELID), 'USAGE') THEN
        RAISE EXCEPTION 'match profile "%" is shipped with modb and read-only', OLD.name
            USING ERRCODE = 'insufficient_privilege',
                  HINT = format('edit a copy: INSERT INTO modb.match_profiles (name, settings) '
                                'SELECT ''mine'', settings FROM modb.match_profiles WHERE name = %L', OLD.name);
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.match_profiles_guard() IS
    'Trigger: shipped match profiles change only with the extension (its owner); users edit their own copies';

CREATE TRIGGER match_profiles_guard BEFORE UPDATE ON modb.match_profiles
    FOR EACH ROW EXECUTE FUNCTION modb.match_profiles_guard();

-- A match profile resolved for one query (modb.match_plan, built by 79_match_plan.sql), the session's
-- knobs it reads, and its thresholds per joint.

CREATE TYPE modb.match_plan AS (
    joints                     int[],
    position_threshold         float8[],
    angle_threshold            float8[],
    velocity_threshold         float8[],
    angular_velocity_threshold float8[],
    norm                       text,
    velocity_terms             boolean,
    heading_weight             float8,
    box_half_width             float8[],
    continuity_weight          float8,
    lookahead_distance         float8,
    graph_id                   bigint,
    graph_lookahead            boolean,
    graph_cost_to_go           boolean,
    annotations                text[]
);
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, whether it ranks by the graph''s cost-to-go, and the annotation names candidates keep to (modb.annotation_spec), if any';

CREATE FUNCTION modb.session_settings()
RETURNS text[]
LANGUAGE c STABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_session_settings';
COMMENT ON FUNCTION modb.session_settings() IS
    'Names of this session''s modb.* settings that have a value (pg_settings does not list them: they are placeholders)';

CREATE FUNCTION modb._thresholds(spec jsonb, joints text[], included text[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
BEGIN ATOMIC
    SELECT array_agg(CASE WHEN j <> ALL (included) THEN 'Infinity'::float8
                          WHEN jsonb_typeof(spec) = 'number' THEN spec::text::float8
                          ELSE coalesce((spec->>j)::float8, (spec->>'default')::float8) END ORDER BY n)
      FROM unnest(joints) WITH ORDINALITY AS t(j, n);
END;
COMMENT ON FUNCTION modb._thresholds(jsonb, text[], text[]) IS
    'Internal: a threshold per joint from a number or {"default": x, "<joint>": y}; Infinity for joints not included';
