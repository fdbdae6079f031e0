-- The continuity ratio of a seam (select_next_snippet's exact check). In C since 0.7.0: the same arithmetic
-- as the inlined SQL expression before it (src/continuity.c), ~100x faster a candidate. CREATE OR REPLACE:
-- upgrades include this file.

CREATE OR REPLACE FUNCTION modb.continuity_ratio_native(a modb.terminators, b modb.terminators, plan modb.match_plan)
RETURNS float8
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_continuity_ratio';
COMMENT ON FUNCTION modb.continuity_ratio_native(modb.terminators, modb.terminators, modb.match_plan) IS
    'Internal: modb.continuity_ratio''s arithmetic in C';

CREATE OR REPLACE FUNCTION modb.continuity_ratio(a modb.terminators, b modb.terminators, plan modb.match_plan)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- A SQL wrapper, inlined into the selection's plan, around the C function.
RETURN modb.continuity_ratio_native(a, b, plan);
COMMENT ON FUNCTION modb.continuity_ratio(modb.terminators, modb.terminators, modb.match_plan) IS
    'max over included joints of difference/threshold (position by the profile''s norm, quaternion angle, velocities): <= 1 within thresholds';
