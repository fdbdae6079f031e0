-- The search box of a match plan around a terminator's features (select_next_snippet's index condition).

CREATE FUNCTION modb.match_box(features cube, plan modb.match_plan, scale float8)
RETURNS cube
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- + 1e-4: terminators store float4 and features float8; the margin keeps every candidate that passes
    -- the exact check inside the box, so a row's level depends on its ratio alone.
    SELECT cube(array_agg(cube_ll_coord(features, i) - scale * (plan).box_half_width[i] - 1e-4 ORDER BY i),
                array_agg(cube_ll_coord(features, i) + scale * (plan).box_half_width[i] + 1e-4 ORDER BY i))
      FROM generate_series(1, cube_dim(features)) AS i;
END;
COMMENT ON FUNCTION modb.match_box(cube, modb.match_plan, float8) IS
    'The per-dimension search box around a feature point: each feature +- scale x its joint''s threshold';
