-- The checks of a select_next_snippet request, with errors that say what is wrong.

CREATE FUNCTION modb.check_request(prev_snippet bigint, target float8[], k int, collection text)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    IF target IS NULL OR array_length(target, 1) NOT IN (2, 3) OR array_ndims(target) <> 1
       OR EXISTS (SELECT FROM unnest(target) v WHERE v IS NULL OR v = 'NaN' OR v IN ('Infinity', '-Infinity')) THEN
        RAISE EXCEPTION 'target must be {x, z} or {x, y, z} in metres, got %', coalesce(target::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF k IS NULL OR k < 1 THEN
        RAISE EXCEPTION 'k must be at least 1, got %', coalesce(k::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF prev_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = prev_snippet) THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'prev_snippet is a modb.snippets id, or NULL to start';
    END IF;
    IF collection IS NOT NULL AND modb.find_collection(collection) IS NULL THEN
        RAISE EXCEPTION 'no collection "%"', collection USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_request(bigint, float8[], int, text) IS
    'Raises a clear error for a select_next_snippet request that cannot be answered (bad target or k, unknown snippet or collection)';
