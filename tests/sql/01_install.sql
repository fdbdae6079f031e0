-- The extension installs, drops and re-installs cleanly; objects, comments and declarations as documented.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(25);

SELECT has_extension('modb');
SELECT has_schema('modb');
SELECT tables_are('modb', ARRAY['collections', 'skeletons', 'clips', 'clip_versions', 'models', 'graphs',
                               'snippet_sources', 'terminators', 'snippets', 'match_profiles', 'graph_snippets',
                               'graph_transitions', 'graph_names', 'snippet_blocks', 'generations', 'access_tokens',
                               'audit_log', 'clip_segments', 'edit_scripts', 'repaired_rows', 'processed_data',
                               'model_inputs']);
SELECT views_are('modb', ARRAY['current_clips', 'processed_data_status', 'model_status']);
SELECT functions_are('modb', ARRAY[
    'skeleton_identity', 'unit_quaternions_ok', 'finite_ok', 'skeleton_joint_names', 'joint_map_ok', 'mirror_pairs_ok',
    'annotations_ok', 'clip_versions_before_insert', 'clip_versions_before_update', 'skeletons_before_update',
    'collection_path', 'find_collection', 'ensure_collection', 'forward_kinematics', 'world_positions',
    'skeleton_pose_key', 'standard_joints', 'feature_names', 'quat_angle', 'max_joint_angle', 'weighted_joint_angle',
    'match_knobs', 'session_settings', 'match_plan', '_thresholds', 'continuity_ratio', 'continuity_ratio_native', 'match_box', 'target_cost', 'aim_point', 'approach_cost', 'collection_subtree',
    'check_request', 'build_snippets', 'select_next_snippets', 'select_next_snippet', 'world_to_local', 'select_next_snippet_world',
    'local_to_world', 'synthesis_goal', 'synthesis_step_end', 'check_synthesis', 'synthesize', 'fill_futures', 'build_transition_graph', 'transition_graph_inputs', 'transition_graph_terminators', 'store_transition_graph', 'transition_key', 'cost_to_go', 'candidates_examined',
    'feature_cube_penalty', 'feature_cube_picksplit', 'match_profiles_guard', '_knob_boolean', '_knob_number',
    'check_world_request', 'frame_key', 'select_next_snippets_reference', 'explain_selection',
    'add_snippet_blocks', 'next_generation', 'snippets_inserted', 'snippets_updated', 'pack_snippet_blocks',
    'synthesis_chain', 'graph_is_current', 'snippet_pools', 'default_graph', 'rest_speed', 'walk_speed', 'end_speed',
    'select_snippet_ending', 'select_synthesis_step', 'snippets_ending_within', 'can_rest', 'token_grant',
    'audit_log_refuse', 'annotation_spec', 'annotated', 'collections_before_update', '_collection_id',
    'rename_collection', 'move_collection', 'delete_collection', 'delete_clip', 'delete_clip_version',
    'restore_clip_version', 'clip_segments_after_delete', 'clip_versions_not_segment', 'split_by_annotation',
    'joint_axes_ok', 'retarget', 'apply_edit_script', 'raise_in_words', '_build_snippets', '_retarget',
    '_apply_edit_script', 'joint_axes_problem', 'skeletons_check_documents', 'edit_script_problems',
    'edit_scripts_check_commands', 'collections_check_name', 'terminators_updated',
    'select_snippet_ending_reference', 'annotate_steps', '_annotate_steps', 'align_primitive', '_align_primitive',
    'annotate_action', '_annotate_action',
    'models_version_rules', 'model_document_problems', 'model_mixture_md5', 'models_check_documents',
    'models_keep_inputs', 'models_keep_what_graphs_name', 'tree_shape', 'sample_motion', '_sample_motion',
    'model_graph_problem', 'model_graphs_check',
    'synthesize_from_models', '_synthesize_from_models', 'prepared_models', 'library_version']);
SELECT is((SELECT o.opcname::text FROM pg_index i JOIN pg_opclass o ON o.oid = i.indclass[0]
            WHERE i.indexrelid = 'modb.snippets_begin_features_idx'::regclass), 'cube_feature_ops',
          'the feature index uses modb''s operator class');
SELECT col_type_is('modb', 'clip_versions', 'rotations', 'real[]', 'rotations is real[]');
SELECT col_type_is('modb', 'clip_versions', 'translations', 'real[]', 'translations is real[]');
SELECT col_is_pk('modb', 'clip_versions', ARRAY['clip_id', 'version'], 'primary key (clip_id, version)');
SELECT col_type_is('modb', 'graph_transitions', 'cost_to_go', 'real[]', 'a graph''s cost-to-go is real[]');
SELECT has_trigger('modb', 'clip_versions', 'clip_versions_before_update', 'immutability trigger');

SELECT is((SELECT count(*) FROM pg_proc WHERE pronamespace = 'modb'::regnamespace
            AND obj_description(oid, 'pg_proc') IS NULL), 0::bigint, 'every function has a COMMENT');
SELECT is((SELECT count(*) FROM pg_class WHERE relnamespace = 'modb'::regnamespace AND relkind IN ('r', 'v')
            AND obj_description(oid, 'pg_class') IS NULL), 0::bigint, 'every table and view has a COMMENT');
-- Parallel labels: tests/test_parallel_safety.py runs every PARALLEL SAFE function in a parallel worker.
SELECT is((SELECT count(*) FROM pg_proc WHERE pronamespace = 'modb'::regnamespace AND prosecdef
             AND proname NOT IN ('token_grant', 'delete_collection', 'delete_clip', 'delete_clip_version',
                                 'models_keep_inputs')), 0::bigint,
    'no SECURITY DEFINER function but token_grant, the deleting functions and the trigger keeping model_inputs');
SELECT ok((SELECT l.lanname = 'sql' AND p.proconfig = ARRAY['search_path=pg_catalog, pg_temp']
             FROM pg_proc p JOIN pg_language l ON l.oid = p.prolang WHERE p.oid = 'modb.token_grant(bytea)'::regprocedure),
          'token_grant (SECURITY DEFINER: it answers for one hash, so no role reads the tokens) is SQL with a fixed search_path');
SELECT is((SELECT array_agg(p.proname::text ORDER BY p.proname) FROM pg_proc p JOIN pg_language l ON l.oid = p.prolang
            WHERE p.pronamespace = 'modb'::regnamespace AND p.prosecdef AND p.proname LIKE 'delete%'
              AND l.lanname = 'plpgsql' AND p.proconfig = ARRAY['search_path=pg_catalog, pg_temp']
              AND has_function_privilege('modb_loader', p.oid, 'EXECUTE')
              AND NOT has_function_privilege('modb_reader', p.oid, 'EXECUTE')),
          ARRAY['delete_clip', 'delete_clip_version', 'delete_collection'],
          'the deleting functions (SECURITY DEFINER: no table-level DELETE for the loader) are PL/pgSQL with a fixed search_path, for modb_loader only');
SELECT volatility_is('modb', 'unit_quaternions_ok', ARRAY['real[]', 'double precision'], 'immutable');
SELECT volatility_is('modb', 'world_positions', ARRAY['bigint', 'integer'], 'stable');
SELECT is_strict('modb', 'unit_quaternions_ok', ARRAY['real[]', 'double precision']);

SELECT set_eq(
    $$SELECT c::regclass::text FROM pg_extension, unnest(extconfig) AS c WHERE extname = 'modb'$$,
    ARRAY['modb.collections', 'modb.collections_id_seq', 'modb.skeletons', 'modb.skeletons_id_seq',
          'modb.clips', 'modb.clips_id_seq', 'modb.clip_versions', 'modb.models', 'modb.models_id_seq',
          'modb.graphs', 'modb.graphs_id_seq', 'modb.clip_segments', 'modb.edit_scripts', 'modb.snippet_sources', 'modb.terminators', 'modb.terminators_id_seq',
          'modb.snippets', 'modb.snippets_id_seq', 'modb.match_profiles', 'modb.graph_snippets', 'modb.graph_transitions',
          'modb.graph_names', 'modb.access_tokens', 'modb.access_tokens_id_seq', 'modb.audit_log',
          'modb.audit_log_id_seq', 'modb.repaired_rows', 'modb.repaired_rows_id_seq', 'modb.processed_data',
          'modb.processed_data_id_seq'],
    'every data table and id sequence is registered for pg_dump');

DROP EXTENSION modb;
SELECT hasnt_schema('modb', 'DROP EXTENSION removes the schema');
SELECT has_role('modb_reader', 'modb_reader outlives DROP EXTENSION');
SELECT has_role('modb_loader', 'modb_loader outlives DROP EXTENSION');
CREATE EXTENSION modb CASCADE;
SELECT has_table('modb', 'clip_versions', 're-install after a drop works');
SELECT is((SELECT extversion FROM pg_extension WHERE extname = 'modb'),
          (SELECT default_version FROM pg_available_extensions WHERE name = 'modb'), 're-installed version');

SELECT * FROM finish();
ROLLBACK;
