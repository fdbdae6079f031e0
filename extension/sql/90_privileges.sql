-- Least privilege: modb_reader reads, modb_loader (a member of modb_reader) writes.
GRANT USAGE ON SCHEMA modb TO modb_reader, modb_loader;
GRANT SELECT ON ALL TABLES IN SCHEMA modb TO modb_reader;
GRANT INSERT ON modb.collections, modb.skeletons, modb.clips, modb.clip_versions TO modb_loader;
GRANT UPDATE (meta) ON modb.collections, modb.clips, modb.clip_versions TO modb_loader;
GRANT UPDATE (name, joint_map, mirror_pairs, meta) ON modb.skeletons TO modb_loader;
GRANT INSERT, UPDATE, DELETE ON modb.models, modb.graphs TO modb_loader;
GRANT USAGE ON ALL SEQUENCES IN SCHEMA modb TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.ensure_collection(text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.ensure_collection(text) TO modb_loader;
GRANT INSERT, DELETE ON modb.graph_snippets, modb.graph_transitions TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) TO modb_loader;
