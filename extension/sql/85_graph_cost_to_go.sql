-- Reading a transition graph's cost-to-go (modb_kernel/cost_to_go.py says what it is and how it is
-- computed): the bilinear read in (angle, log radius) of the kernel's `interpolation`, in SQL, so that
-- select_next_snippet ranks candidates by it inside its one query. Upgrades include this file (after adding
-- the column).

COMMENT ON COLUMN modb.graph_transitions.cost_to_go IS
    'Seconds from this snippet''s end until a chain through the graph reaches a goal, for goals on the polar grid graphs.data->''cost_to_go'' describes (read with modb.cost_to_go); NULL in graphs built before 0.6.0';

CREATE OR REPLACE FUNCTION modb.cost_to_go(costs real[], goal float8[], grid jsonb)
RETURNS float8
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN (SELECT CASE WHEN r <= inner_radius THEN 0
                    ELSE (1 - wa) * ((1 - wj) * costs[a0 * rings + j0 + 1] + wj * costs[a0 * rings + j0 + 2])
                         + wa * ((1 - wj) * costs[a1 * rings + j0 + 1] + wj * costs[a1 * rings + j0 + 2])
                         + greatest(r - outer_radius, 0) / speed END
          FROM (SELECT r, inner_radius, outer_radius, speed, rings,
                       angle - floor(angle) AS wa, floor(angle)::int % angles AS a0, (floor(angle)::int + 1) % angles AS a1,
                       ring - floor(ring) AS wj, floor(ring)::int AS j0
                  FROM (SELECT r, inner_radius, outer_radius, speed, rings, angles,
                               least(greatest(ln(greatest(r, 1e-9) / inner_radius) / ln(outer_radius / inner_radius) * (rings - 1), 0),
                                     rings - 1 - 1e-9) AS ring,
                               (theta - 2 * pi() * floor(theta / (2 * pi()))) / (2 * pi() / angles) AS angle
                          FROM (SELECT sqrt(goal[1] ^ 2 + goal[array_length(goal, 1)] ^ 2) AS r,
                                       atan2(goal[1], goal[array_length(goal, 1)]) AS theta,
                                       (grid->>'inner_radius')::float8 AS inner_radius, (grid->>'outer_radius')::float8 AS outer_radius,
                                       (grid->>'speed')::float8 AS speed, (grid->>'rings')::int AS rings,
                                       (grid->>'angles')::int AS angles) given) ring) cell);
COMMENT ON FUNCTION modb.cost_to_go(real[], float8[], jsonb) IS
    'Seconds until a chain through a transition graph reaches goal ({x, z} or {x, y, z}, metres in the heading frame at a snippet''s end), read from that snippet''s cost_to_go (modb.graph_transitions) on the grid graphs.data->''cost_to_go'' describes';
