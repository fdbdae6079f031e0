-- The session knobs are real settings (listed, typed by their check, refused when misspelt or out of range
-- once the library is loaded), and every change of what sessions cache takes a new generation.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(12);

LOAD 'modb';  -- what session_preload_libraries does for the embedded cluster
SELECT set_eq($$SELECT substr(name, 6) FROM pg_settings WHERE name LIKE 'modb.%' AND name <> 'modb.foot_hold'$$,
              $$SELECT unnest(modb.match_knobs())$$, 'every knob is listed in pg_settings');
SELECT is((SELECT vartype || ' ' || boot_val FROM pg_settings WHERE name = 'modb.foot_hold'), 'bool on',
          'modb.foot_hold, the one setting beside the knobs: a boolean, on by default');
SELECT throws_ok($$SET modb.foot_hold = 'sometimes'$$, '22023', NULL, 'modb.foot_hold takes a boolean only');
SELECT is((SELECT count(*) FROM pg_settings WHERE name LIKE 'modb.%' AND name <> 'modb.foot_hold'
                                              AND short_desc NOT LIKE '%profile%'), 0::bigint,
          'each says how to get the profile''s value');
SELECT is((SELECT short_desc LIKE '%(metres)%' FROM pg_settings WHERE name = 'modb.position_threshold'), true,
          'a threshold states its unit');
SELECT throws_like($$SET modb.positon_threshold = 0.1$$, '%modb.positon_threshold%', 'a misspelt knob is refused at SET');
SELECT throws_ok($$SET modb.position_threshold = -1$$, '22023', NULL, 'a negative threshold is refused at SET');
SELECT throws_ok($$SET modb.velocity_terms = maybe$$, '22023', NULL, 'a boolean knob takes on or off');
SELECT throws_ok($$SET modb.joints = 'pelvis,tail'$$, '22023', NULL, 'joints must be standard joints');
SET LOCAL modb.position_threshold = 'profile';
SELECT lives_ok($$SET LOCAL modb.position_threshold = '0.2'$$, 'a number in range is taken');

CREATE TEMP TABLE seen AS SELECT name, generation FROM modb.generations;
INSERT INTO modb.match_profiles (name, settings) SELECT 'pgtap', settings FROM modb.match_profiles WHERE name = 'default';
SELECT ok((SELECT g.generation > s.generation FROM modb.generations g JOIN seen s USING (name) WHERE name = 'match_plans'),
          'a new profile takes a new generation of plans');
SELECT ok((SELECT g.generation = s.generation FROM modb.generations g JOIN seen s USING (name) WHERE name = 'snippet_blocks'),
          'and leaves the blocks'' generation alone');

SELECT * FROM finish();
ROLLBACK;
