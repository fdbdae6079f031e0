-- The objective of select_next_snippet: how far a candidate leaves the character from its goal.

CREATE FUNCTION modb.target_cost(net_translation float8[], net_heading float8, target float8[], heading_weight float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
RETURN CASE WHEN array_length(target, 1) = 3
            THEN sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[2] - target[2]) ^ 2 + (net_translation[3] - target[3]) ^ 2)
            ELSE sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[3] - target[2]) ^ 2) END
       + heading_weight * abs(atan2(sin(net_heading - atan2(target[1], target[array_length(target, 1)])),
                                    cos(net_heading - atan2(target[1], target[array_length(target, 1)]))));
COMMENT ON FUNCTION modb.target_cost(float8[], float8, float8[], float8) IS
    'Distance (m) from a snippet''s net translation to the target {x, z} or {x, y, z}, plus heading_weight x |heading change - direction of the target| (radians)';

CREATE OR REPLACE FUNCTION modb.aim_point(target float8[], lookahead_distance float8)
RETURNS float8[]
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- Scales the ground part ({x, z}, or x and z of {x, y, z}) down to lookahead_distance; NULL: the target.
RETURN (SELECT CASE WHEN lookahead_distance IS NULL OR lookahead_distance >= ground THEN target
                    WHEN array_length(target, 1) = 3
                    THEN ARRAY[target[1] * lookahead_distance / ground, target[2], target[3] * lookahead_distance / ground]
                    ELSE ARRAY[target[1] * lookahead_distance / ground, target[2] * lookahead_distance / ground] END
          FROM (SELECT sqrt(target[1] ^ 2 + target[array_length(target, 1)] ^ 2) AS ground) g);
COMMENT ON FUNCTION modb.aim_point(float8[], float8) IS
    'The point the objective scores against: the target, or the point lookahead_distance metres (on the ground) along the way to it when it is farther';

CREATE OR REPLACE FUNCTION modb.approach_cost(net_translation float8[], future_translation float8[],
                                              future_heading float8, aim float8[], heading_weight float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- The nearer of the two points on the candidate's way: where it ends, and where playing on leads. The end
-- counts so that a near goal is reached: scored by the 1.5 s point alone, a snippet stopping on the goal
-- loses to one whose play-on curves back to it, and the avatar circles the goal (docs/synthesis.md "Synthesis quality").
RETURN least(modb.target_cost(net_translation, future_heading, aim, heading_weight),
             modb.target_cost(future_translation, future_heading, aim, heading_weight));
COMMENT ON FUNCTION modb.approach_cost(float8[], float8[], float8, float8[], float8) IS
    'The objective of select_next_snippet: distance (m) from the aim point to the nearer of the snippet''s end and where playing on leads, plus heading_weight x |heading change where playing on leads - direction of the aim| (radians)';
