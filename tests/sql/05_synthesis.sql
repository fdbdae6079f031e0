-- Synthesis helpers: placement arithmetic checked against values worked out by hand, and declarations.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(15);

-- Facing +X (heading pi/2): 1 m forward is +X, 1 m to the left (local x) is -Z.
SELECT ok((SELECT max(abs(a - b)) < 1e-12 FROM unnest(modb.local_to_world('{1,0,2}', pi() / 2, '{0,0.3,1}'),
                                                      ARRAY[2, 0.3, 2]::float8[]) AS t(a, b)),
          'local_to_world: forward when facing +X');
SELECT ok((SELECT max(abs(a - b)) < 1e-12 FROM unnest(modb.local_to_world('{1,0,2}', pi() / 2, '{1,0}'),
                                                      ARRAY[1, 1]::float8[]) AS t(a, b)),
          'local_to_world: {x, z} to the left when facing +X');
SELECT ok((SELECT max(abs(a - b)) < 1e-9 FROM unnest(
              modb.world_to_local('{-3,0,5}', 2.5, modb.local_to_world('{-3,0,5}', 2.5, '{0.7,0.2,-1.9}')),
              ARRAY[0.7, 0.2, -1.9]::float8[]) AS t(a, b)),
          'world_to_local undoes local_to_world');
SELECT is((SELECT end_heading FROM modb.synthesis_step_end('{0,0,0}', 3.0, '{0,0,1}', 0.5, '{0,0}', 0.5)),
          atan2(sin(3.5::float8), cos(3.5::float8)), 'headings wrap to (-pi, pi]');
SELECT ok((SELECT reached AND end_position[2] = 0 FROM modb.synthesis_step_end('{0,0,0}', 0, '{0.1,0.9,1}', 0, '{0,1.2}', 0.5)),
          'within the radius on the ground (the pelvis height change is not travel)');
SELECT ok((SELECT NOT reached FROM modb.synthesis_step_end('{0,0,0}', 0, '{0,0,1}', 0, '{0,1.6}', 0.5)),
          'outside the radius');
SELECT is(modb.synthesis_goal('{{1,2},{3,4}}', 2), '{3,4}'::float8[], 'goals by row');
SELECT volatility_is('modb', 'synthesize',
    ARRAY['double precision[]', 'integer', 'bigint', 'double precision[]', 'double precision', 'text', 'text',
          'double precision', 'double precision', 'text'], 'volatile');
SELECT volatility_is('modb', 'synthesis_chain',
    ARRAY['double precision[]', 'integer', 'bigint', 'double precision[]', 'double precision', 'text', 'text',
          'double precision', 'double precision', 'boolean'], 'stable');

-- The defaults synthesis takes (89_synthesis.sql), on collections and a graph row made here.
SELECT is((SELECT count(*) FROM modb.snippet_pools()), 0::bigint, 'no snippets: no pools');
SELECT is(modb.default_graph('default', 'a/b'), NULL, 'no graph: none to use');
INSERT INTO modb.graph_names VALUES ('over a', 'transitions'), ('everywhere', 'transitions'), ('old', 'transitions');
INSERT INTO modb.graphs (name, kind, data) VALUES
    ('everywhere', 'transitions', '{"profile": "default", "collection": null, "snippets": 0, "kept": 0, "transition_key": {}, "cost_to_go": {}}'),
    ('over a', 'transitions', '{"profile": "default", "collection": "a", "snippets": 0, "kept": 0, "transition_key": {}, "cost_to_go": {}}'),
    ('old', 'transitions', '{"profile": "default", "collection": "a/b", "snippets": 0, "kept": 0}');
SELECT is(modb.default_graph('default', 'a/b'), 'over a',
          'the nearest containing collection''s graph; a graph without stored transitions is stale');
SELECT is(modb.default_graph('default', 'ab'), 'everywhere', 'a name that only starts like the collection does not contain it');
SELECT is(modb.default_graph('other', 'a'), NULL, 'only graphs of the profile');
SELECT throws_ok($$SELECT * FROM modb.synthesize('{{0,1}}', 3, start_snippet => 12345)$$, '22023', 'no snippet 12345',
                 'an unknown start snippet is an error');

SELECT * FROM finish();
ROLLBACK;
