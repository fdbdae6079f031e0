-- 0.9.0: hardening. Snippets are built in bounded memory and a loader role can build them; the loader
-- role gets only what loading needs; selection refuses thresholds and targets it cannot honour.

-- The frame checks of clip_versions' constraints in C (constant memory for a clip of any length).
CREATE OR REPLACE FUNCTION modb.unit_quaternions_ok(rotations real[], tolerance float8 DEFAULT 1e-5)
RETURNS boolean
LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_unit_quaternions_ok';
CREATE OR REPLACE FUNCTION modb.finite_ok(elements real[])
RETURNS boolean
LANGUAGE C IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_finite_ok';

-- The loader role gets only what loading needs: columns the server fills are not its to give, and no
-- table-level UPDATE or DELETE on a table the selection reads (either lets a role LOCK it against every
-- reader). Old versions' snippets and a graph's rows go by ON DELETE CASCADE, which runs as the owner.
REVOKE INSERT ON modb.collections, modb.skeletons, modb.clips, modb.clip_versions FROM modb_loader;
REVOKE DELETE ON modb.terminators, modb.snippets, modb.graph_snippets, modb.graph_transitions FROM modb_loader;
REVOKE INSERT, UPDATE, DELETE ON modb.match_profiles FROM modb_loader;
REVOKE INSERT, UPDATE, DELETE ON modb.graphs FROM modb_loader;
GRANT UPDATE (future_translation, future_heading) ON modb.snippets TO modb_loader;
GRANT INSERT (name, settings, comment) ON modb.match_profiles TO modb_loader;
GRANT UPDATE (settings, comment) ON modb.match_profiles TO modb_loader;
--@include 90_privileges.sql
--@include 91_shipped_profiles_guard.sql
--@include 92_graph_names.sql
-- Selection input
-- Every knob checked against its range at each selection (an error names the knob, its value and the
-- allowed range); targets, k and select_next_snippet_world's arguments checked before any LIMIT; synthesize's
-- NaN radius and exclusion refused; the exclude filter linear in the length of exclude (each fragment is
-- CREATE OR REPLACE throughout).
--@include 79_match_plan.sql
--@include 86_select_request.sql
--@include 87_select.sql
--@include 89_synthesize.sql
