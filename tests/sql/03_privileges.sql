-- Least privilege: modb_reader reads, modb_loader writes (and reads); neither can rewrite motion.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(33);

SELECT table_privs_are('modb', t, 'modb_reader', ARRAY['SELECT'], 'modb_reader may only SELECT modb.' || t)
  FROM unnest(ARRAY['collections', 'skeletons', 'clips', 'clip_versions', 'models', 'graphs', 'current_clips']) AS t;
SELECT table_privs_are('modb', 'clip_versions', 'modb_loader', ARRAY['SELECT'],
                       'modb_loader has no table-wide write on clip versions (column grants only)');
SELECT ok(has_column_privilege('modb_loader', 'modb.clip_versions', 'rotations', 'INSERT')
          AND NOT has_column_privilege('modb_loader', 'modb.clip_versions', 'created_by', 'INSERT')
          AND NOT has_column_privilege('modb_loader', 'modb.clip_versions', 'created_at', 'INSERT'),
          'modb_loader inserts clip versions, the server says who and when');
SELECT ok(has_column_privilege('modb_loader', 'modb.clip_versions', 'meta', 'UPDATE')
          AND NOT has_column_privilege('modb_loader', 'modb.clip_versions', 'rotations', 'UPDATE'),
          'modb_loader may edit meta but not the frames');
SELECT ok(has_table_privilege('modb_loader', 'modb.clips', 'SELECT'), 'modb_loader reads through modb_reader');
SELECT ok(has_column_privilege('modb_loader', 'modb.skeletons', 'joint_map', 'UPDATE')
          AND has_column_privilege('modb_loader', 'modb.skeletons', 'mirror_pairs', 'UPDATE')
          AND NOT has_column_privilege('modb_loader', 'modb.skeletons', 'hierarchy', 'UPDATE'),
          'modb_loader may edit joint maps and pairs, not hierarchies');
SELECT table_privs_are('modb', 'models', 'modb_loader', ARRAY['SELECT', 'INSERT', 'UPDATE', 'DELETE'],
                       'modb_loader manages models');
SELECT ok(has_sequence_privilege('modb_loader', 'modb.clips_id_seq', 'USAGE')
          AND NOT has_sequence_privilege('modb_reader', 'modb.clips_id_seq', 'USAGE'),
          'only modb_loader draws ids');
SELECT ok(NOT has_table_privilege('modb_loader', 'modb.clip_versions', 'DELETE')
          AND NOT has_table_privilege('modb_loader', 'modb.skeletons', 'DELETE'), 'modb_loader deletes no motion');
SELECT ok(NOT has_function_privilege('modb_reader', 'modb.ensure_collection(text)', 'EXECUTE'),
          'modb_reader cannot create collections');
SELECT ok(has_function_privilege('modb_reader', 'modb.world_positions(bigint, integer)', 'EXECUTE'),
          'modb_reader may compute world positions');

SET LOCAL ROLE modb_reader;
SELECT lives_ok($$SELECT count(*) FROM modb.current_clips$$, 'reader reads');
SELECT throws_ok($$INSERT INTO modb.collections (name) VALUES ('x')$$, '42501', NULL, 'reader cannot write');
RESET ROLE;

SET LOCAL ROLE modb_loader;
SELECT lives_ok($$SELECT modb.ensure_collection('loaded/by/loader')$$, 'loader creates collections');
SELECT is(modb.collection_path(modb.find_collection('loaded/by/loader')), 'loaded/by/loader', 'the path round-trips');
SELECT throws_ok($$DELETE FROM modb.clips$$, '42501', NULL, 'loader cannot delete clips');
SELECT throws_ok($$UPDATE modb.clip_versions SET rotations = rotations$$, '42501', NULL, 'loader cannot rewrite frames');
SELECT throws_ok($$LOCK modb.snippets IN ACCESS EXCLUSIVE MODE$$, '42501', NULL, 'loader cannot lock out the readers');
SELECT throws_ok($$UPDATE modb.match_profiles SET comment = 'mine now' WHERE name = 'default'$$, '42501', NULL,
                 'loader cannot edit a shipped profile');
SELECT throws_ok($$DELETE FROM modb.snippets$$, '42501', NULL, 'loader deletes snippets only through their source');
SELECT lives_ok($$UPDATE modb.snippets SET future_heading = future_heading WHERE false$$, 'loader fills futures');
RESET ROLE;
SELECT ok(has_function_privilege('modb_loader', 'modb.pack_snippet_blocks(float8)', 'EXECUTE')
          AND NOT has_function_privilege('modb_reader', 'modb.pack_snippet_blocks(float8)', 'EXECUTE')
          AND has_table_privilege('modb_loader', 'modb.snippet_blocks', 'DELETE')
          AND NOT has_table_privilege('modb_reader', 'modb.snippet_blocks', 'DELETE'),
          'the loader packs snippet blocks, a reader cannot');
SELECT ok(NOT has_table_privilege('modb_reader', 'modb.access_tokens', 'SELECT')
          AND NOT has_table_privilege('modb_loader', 'modb.access_tokens', 'SELECT'),
          'no modb role reads the tokens'' table');
SELECT ok(has_function_privilege('modb_reader', 'modb.token_grant(bytea)', 'EXECUTE')
          AND NOT has_function_privilege('public', 'modb.token_grant(bytea)', 'EXECUTE'),
          'a reader may ask about one token''s hash; PUBLIC may not');
SET LOCAL ROLE modb_loader;
SELECT lives_ok($$INSERT INTO modb.audit_log (token_name, action, object) VALUES ('t', 'test', 'nothing')$$,
                'the loader records writes');
SELECT throws_ok($$UPDATE modb.audit_log SET token_name = 'other'$$, '42501', NULL, 'the loader cannot edit the log');
RESET ROLE;
SELECT throws_ok($$DELETE FROM modb.audit_log$$, '42501', NULL, 'not even the owner deletes from the log');

SELECT * FROM finish();
ROLLBACK;
