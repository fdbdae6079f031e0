-- The quaternion-angle operator and the configuration-level functions, on known values.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(28);

SELECT is(round(('{1,0,0,0}'::float8[] OPERATOR(modb.<%>) ARRAY[cos(pi() / 4), sin(pi() / 4), 0, 0])::numeric, 12),
          round((pi() / 2)::numeric, 12), '90 degrees about x');
SELECT is(('{0.5,0.5,0.5,0.5}'::float8[] OPERATOR(modb.<%>) '{-0.5,-0.5,-0.5,-0.5}'), 0::float8, 'q and -q: the same rotation');
SELECT is(round(('{1,0,0,0}'::float8[] OPERATOR(modb.<%>) '{0,0,1,0}')::numeric, 12), round(pi()::numeric, 12),
          'half a turn: pi');
SELECT ok(abs(('{1,0,0,0}'::float8[] OPERATOR(modb.<%>) ARRAY[cos(5e-7), 0, 0, sin(5e-7)]) - 1e-6) < 1e-12,
          'a micro-radian stays accurate (no acos near 1)');
SELECT ok(abs(('{1,0,0,0}'::float8[] OPERATOR(modb.<%>) ARRAY[sin(5e-7), cos(5e-7), 0, 0]) - (pi() - 1e-6)) < 1e-12,
          'and so does pi minus a micro-radian');
SELECT is(('{1,0,0,0}'::float8[] OPERATOR(modb.<%>) ARRAY[cos(0.3), sin(0.3), 0, 0]),
          (ARRAY[cos(0.3), sin(0.3), 0, 0] OPERATOR(modb.<%>) '{1,0,0,0}'::float8[]), 'commutative');
SELECT is((SELECT oprcom::regoper::text FROM pg_operator WHERE oprname = '<%>' AND oprnamespace = 'modb'::regnamespace),
          'modb.<%>', 'declared as its own commutator');
SELECT volatility_is('modb', 'quat_angle', ARRAY['double precision[]', 'double precision[]'], 'immutable');

-- Two joints: identical, and 0.2 / 0.4 rad apart about z.
SELECT is(modb.max_joint_angle(ARRAY[1, 0, 0, 0, 1, 0, 0, 0]::real[],
                               ARRAY[cos(0.1), 0, 0, sin(0.1), cos(0.2), 0, 0, sin(0.2)]::real[], '{0,1}')::numeric(10, 5),
          0.4::numeric(10, 5), 'max over joints');
SELECT is(modb.max_joint_angle(ARRAY[1, 0, 0, 0, 1, 0, 0, 0]::real[],
                               ARRAY[cos(0.1), 0, 0, sin(0.1), cos(0.2), 0, 0, sin(0.2)]::real[], '{0}')::numeric(10, 5),
          0.2::numeric(10, 5), 'max over a joint subset');
SELECT is(modb.weighted_joint_angle(ARRAY[1, 0, 0, 0, 1, 0, 0, 0]::real[],
                                    ARRAY[cos(0.1), 0, 0, sin(0.1), cos(0.2), 0, 0, sin(0.2)]::real[], '{0,1}', '{2,0.5}')::numeric(10, 5),
          0.6::numeric(10, 5), 'weighted sum: 2 x 0.2 + 0.5 x 0.4');

SELECT is(modb.target_cost('{1,0,1}', 0, '{1,1}', 0), 0::float8, 'a snippet that ends on the target');
SELECT is(modb.target_cost('{0,0,0}', 0, '{3,0,4}', 0), 5::float8, '{x, y, z} targets: 3-D distance');
SELECT is(round(modb.target_cost('{0,0,1}', 0, '{1,0}', 1)::numeric, 9), round((sqrt(2) + pi() / 2)::numeric, 9),
          'heading term: target to the left (+x) needs a quarter turn');
SELECT is((SELECT array_agg(round(v::numeric, 9)) FROM unnest(modb.world_to_local('{0,0,0}', pi() / 2, '{1,0}')) v),
          '{0,1}'::numeric[], 'facing +X (heading pi/2), a goal at +X is straight ahead');
SELECT is((SELECT array_agg(round(v::numeric, 9)) FROM unnest(modb.world_to_local('{1,0,1}', 0, '{2,5,1}')) v),
          '{1,5,0}'::numeric[], 'facing +Z, a goal one metre to +X is one metre to the left');
SELECT is((SELECT array_agg(round(v::numeric, 9)) FROM unnest(modb.world_to_local('{0,0,0}', pi() / 2, '{1,2,3}')) v),
          '{-3,2,1}'::numeric[], 'facing +X, a {x, y, z} goal at (1, 2, 3) is 1 m ahead, 2 m up, 3 m to the right');
SELECT is(modb.aim_point('{3,4}', 2.5), '{1.5,2}'::float8[], 'a far target: the point 2.5 m toward it');
SELECT is(modb.aim_point('{3,7,4}', 1), '{0.6,7,0.8}'::float8[], '{x, y, z}: the ground part scaled, y kept');
SELECT is(modb.aim_point('{1,1}', 2.5), '{1,1}'::float8[], 'a target nearer than the lookahead: itself');
SELECT is(modb.aim_point('{30,40}', NULL), '{30,40}'::float8[], 'no lookahead: the target itself');
SELECT is(modb.approach_cost('{0,0,1}', '{0,0,3}', 0, '{0,1}', 0), 0::float8, 'a snippet that ends on the aim, though playing on passes it');
SELECT is(modb.approach_cost('{0,0,1}', '{0,0,3}', 0, '{0,2.5}', 0), 0.5::float8, 'the nearer point: where playing on leads');
SELECT is(round(modb.approach_cost('{0,0,1}', '{0,0,3}', pi() / 2, '{0,1}', 1)::numeric, 9), round((pi() / 2)::numeric, 9),
          'the heading term counts once');
SELECT throws_ok($$SELECT modb.match_plan('no such profile')$$, 'P0001', 'unknown match profile "no such profile"',
                 'an unknown profile is an error');
SELECT throws_ok($$SELECT modb.candidates_examined(1, 5)$$, 'P0001',
                 'relax_level must be 0-4 (select_next_snippet''s relax_level), got 5', 'candidates_examined: a level past 4');
SELECT throws_ok($$SELECT modb.candidates_examined(-1, 0)$$, 'P0001', 'no snippet -1', 'candidates_examined: an unknown snippet');
SELECT is(modb.candidates_examined(NULL, 0), (SELECT count(*) FROM modb.snippets), 'a start ranks every snippet');

SELECT * FROM finish();
ROLLBACK;
