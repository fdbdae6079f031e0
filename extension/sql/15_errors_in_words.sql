-- Errors in a user's words (0.17.0). PL/Python puts the Python exception's name before every message
-- it raises ("plpy.Error: ", "spiexceptions.CheckViolation: "), whatever the function does; so each
-- PL/Python function a user calls (modb._NAME) is called through a PL/pgSQL one (modb.NAME) that
-- raises its error again without those names, with its SQLSTATE, detail and hint.

CREATE FUNCTION modb.raise_in_words(message text, error_state text, detail text, hint text)
RETURNS void
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
DECLARE
    words text := regexp_replace(message, '^((plpy|spiexceptions)\.[A-Za-z]+: )+', '');
BEGIN
    IF coalesce(detail, '') <> '' AND coalesce(hint, '') <> '' THEN
        RAISE EXCEPTION USING MESSAGE = words, ERRCODE = error_state, DETAIL = detail, HINT = hint;
    ELSIF coalesce(detail, '') <> '' THEN
        RAISE EXCEPTION USING MESSAGE = words, ERRCODE = error_state, DETAIL = detail;
    ELSIF coalesce(hint, '') <> '' THEN
        RAISE EXCEPTION USING MESSAGE = words, ERRCODE = error_state, HINT = hint;
    END IF;
    RAISE EXCEPTION USING MESSAGE = words, ERRCODE = error_state;
END
$$;
COMMENT ON FUNCTION modb.raise_in_words(text, text, text, text) IS
    'Internal: raises an error again without the Python exception names PL/Python puts before its message (plpy.Error, spiexceptions.X), keeping its SQLSTATE, detail and hint';
