-- Least privilege: modb_reader reads, modb_loader (a member of modb_reader) writes. The grants on the tables
-- and sequences made before this fragment; the fragments after it (access tokens, the audit log, retargeting,
-- edit scripts) grant their own, and must: modb_reader may not read access_tokens or audit_log.
GRANT USAGE ON SCHEMA modb TO modb_reader, modb_loader;
GRANT SELECT ON ALL TABLES IN SCHEMA modb TO modb_reader;
-- Grant only what loading needs. Columns the server fills (ids, created_at, created_by, identity_sha256)
-- are not the loader's to give; and no table-level UPDATE, DELETE or TRUNCATE on a table the selection
-- reads, because any of them also lets a role LOCK it in ACCESS EXCLUSIVE mode and stall every reader.
-- (docs/roles.md lists what each role may and may not do; tests/test_roles.py checks it.)
GRANT INSERT (parent_id, name, meta) ON modb.collections TO modb_loader;
GRANT INSERT (name, hierarchy, joint_map, mirror_pairs, meta) ON modb.skeletons TO modb_loader;
GRANT INSERT (collection_id, name, meta) ON modb.clips TO modb_loader;
GRANT INSERT (clip_id, version, skeleton_id, fps, n_frames, rotations, translations, source_file, source_sha256,
              load_params, meta) ON modb.clip_versions TO modb_loader;
GRANT UPDATE (meta) ON modb.collections, modb.clips, modb.clip_versions TO modb_loader;
GRANT UPDATE (name, joint_map, mirror_pairs, meta) ON modb.skeletons TO modb_loader;
GRANT INSERT, UPDATE, DELETE ON modb.models TO modb_loader;  -- no selection reads models
-- modb.graphs: 83_graphs.sql (with modb.graph_names)
GRANT USAGE ON ALL SEQUENCES IN SCHEMA modb TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.ensure_collection(text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.ensure_collection(text) TO modb_loader;
-- A graph's rows go with its modb.graphs row (ON DELETE CASCADE, which runs as the tables' owner).
GRANT INSERT ON modb.graph_snippets, modb.graph_transitions TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) TO modb_loader;
