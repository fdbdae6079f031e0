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
