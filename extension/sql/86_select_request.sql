-- The checks of a select_next_snippet request, with errors that say what is wrong. CREATE OR REPLACE:
-- upgrades include this file.

CREATE OR REPLACE FUNCTION modb.check_request(prev_snippet bigint, target float8[], k int, collection text)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    -- {x, z} or {x, y, z}: one dimension, subscripts from 1, finite coordinates within 1e9 m (so that no
    -- distance the objective computes overflows). NaN is above every number, so NOT (abs(v) <= 1e9) holds
    -- for it too.
    IF target IS NULL OR array_ndims(target) IS DISTINCT FROM 1 OR cardinality(target) NOT IN (2, 3)
       OR array_lower(target, 1) <> 1
       OR EXISTS (SELECT FROM unnest(target) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target must be {x, z} or {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(target::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value',
                  HINT = 'target is the goal in the avatar''s heading frame at the end of prev_snippet: x left, (y up,) z forward';
    END IF;
    IF k IS NULL OR k < 1 THEN
        RAISE EXCEPTION 'k must be at least 1, got %', coalesce(k::text, 'NULL') USING ERRCODE = 'invalid_parameter_value',
            HINT = 'k is how many of the best continuations select_next_snippets returns';
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

CREATE OR REPLACE FUNCTION modb.check_world_request("position" float8[], heading float8, target_world float8[])
RETURNS float8[]
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
DECLARE
    target float8[];
BEGIN
    IF "position" IS NULL OR array_ndims("position") IS DISTINCT FROM 1 OR cardinality("position") <> 3
       OR array_lower("position", 1) <> 1
       OR EXISTS (SELECT FROM unnest("position") v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'position must be {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce("position"::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF heading IS NULL OR NOT abs(heading) < 'Infinity' THEN
        RAISE EXCEPTION 'heading must be a finite angle in radians (0 faces +Z), got %', coalesce(heading::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF target_world IS NULL OR array_ndims(target_world) IS DISTINCT FROM 1 OR cardinality(target_world) NOT IN (2, 3)
       OR array_lower(target_world, 1) <> 1
       OR EXISTS (SELECT FROM unnest(target_world) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target_world must be {x, z} or {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(target_world::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    target := modb.world_to_local("position", heading, target_world);
    IF EXISTS (SELECT FROM unnest(target) v WHERE NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target_world % is farther than 1e9 m from position %', target_world, "position"
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN target;
END
$$;
COMMENT ON FUNCTION modb.check_world_request(float8[], float8, float8[]) IS
    'Raises a clear error for select_next_snippet_world arguments that cannot be answered (position, heading, target_world); else the goal in the avatar''s heading frame (modb.world_to_local)';
