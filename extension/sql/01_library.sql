-- The modb.so a session runs. Where the server preloads it (shared_preload_libraries: the shared block
-- directory and match plans, 0.29.0), that is the one loaded when the server started, whatever is installed
-- since: an install or update that needs newer C says so, and changes nothing, until the server restarts.
DO $$
BEGIN
    EXECUTE $create$CREATE FUNCTION modb.library_version() RETURNS text LANGUAGE c STABLE PARALLEL SAFE
                    AS 'MODULE_PATHNAME', 'modb_library_version'$create$;
EXCEPTION WHEN undefined_function THEN
    RAISE EXCEPTION 'modb {{VERSION}} needs the modb.so installed with it; this session runs an older one (loaded when the server started, by shared_preload_libraries, or earlier in this session)'
        USING ERRCODE = 'object_not_in_prerequisite_state',
              HINT = 'Restart the server (the embedded one: modb db stop, then modb db start; your own: pg_ctl restart or systemctl restart postgresql@15-main), then run this again in a new session.';
END
$$;
COMMENT ON FUNCTION modb.library_version() IS
    'The version of the modb.so this session runs: where the server preloads it (shared_preload_libraries), the one it loaded when it started';
{{LIBRARY_CHECK}}
