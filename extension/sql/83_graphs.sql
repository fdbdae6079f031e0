-- Transition graphs: which snippets a chain can keep moving and steering among (modb_kernel/transitions.py
-- says why).
-- A graph is a modb.graphs row (kind 'transitions': how it was built and what it holds, in jsonb) and
-- its snippets in modb.graph_snippets, which select_next_snippet reads when the `graph` knob names it.

CREATE TABLE modb.graph_snippets (
    graph_id   bigint NOT NULL REFERENCES modb.graphs (id) ON DELETE CASCADE,
    snippet_id bigint NOT NULL REFERENCES modb.snippets (id) ON DELETE CASCADE,
    PRIMARY KEY (graph_id, snippet_id)
);
COMMENT ON TABLE modb.graph_snippets IS
    'The snippets a transition graph keeps (its largest strongly connected component that turns both ways): with SET modb.graph = ''<name>'' (or "graph" in a profile) select_next_snippet chooses among these only';
CREATE INDEX graph_snippets_snippet_idx ON modb.graph_snippets (snippet_id);  -- for ON DELETE CASCADE
SELECT pg_catalog.pg_extension_config_dump('modb.graph_snippets', '');

CREATE OR REPLACE FUNCTION modb.build_transition_graph(name text, profile text DEFAULT 'default',
                                                       collection text DEFAULT NULL, min_turn_degrees float8 DEFAULT 45)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel graph_build
import json

B = kernel.graph_build
# The reads and the write are SQL functions (84_graph_build_io.sql) that a job worker calls too.
snippets = plpy.execute(plpy.prepare("SELECT * FROM modb.transition_graph_inputs($1, $2, $3)",
                                     ["text", "text", "float8"]), [name, collection, min_turn_degrees])
plan = plpy.execute(plpy.prepare(
    """SELECT to_jsonb(p) - 'box_half_width' AS shown, modb.transition_key(p) AS transition_key, p.*
         FROM modb.match_plan($1) p""", ["text"]), [profile])[0]
plpy.notice(f"modb: transition graph \"{name}\": reading the terminators of {len(snippets)} snippets")
terminators = plpy.execute(plpy.prepare("SELECT * FROM modb.transition_graph_terminators($1)", ["bigint[]"]),
                           [sorted({r["begin_terminator"] for r in snippets} | {r["end_terminator"] for r in snippets})])
try:
    built = B.build(name, snippets, terminators, plan, json.loads(plan["shown"]), json.loads(plan["transition_key"]),
                    profile, collection, min_turn_degrees, notice=lambda text: plpy.notice("modb: " + text))
except B.GraphBuildError as e:
    plpy.error(str(e), hint=e.hint)
del snippets, terminators
return plpy.execute(plpy.prepare(
    "SELECT modb.store_transition_graph($1, $2::jsonb, $3, $4, $5, $6, $7) AS id",
    ["text", "text", "bigint[]", "bigint[]", "bigint[]", "real[]", "int"]),
    [name, json.dumps(built.data), built.kept, built.from_ids, built.to_ids, built.costs.ravel().tolist(),
     built.width])[0]["id"]
$py$;
COMMENT ON FUNCTION modb.build_transition_graph(text, text, text, float8) IS
    'Builds (or rebuilds) the transition graph "name" over the snippets (of the collection): edges are relaxation level 0 of the profile; a snippet is kept when it lies in the largest strongly connected component (per skeleton and rate) among those holding turns of at least min_turn_degrees each way (where snippets lead: future_heading), so a chain restricted to it (SET modb.graph) never runs into a dead end and can face any goal; stores each kept snippet''s level-0 successors and its cost-to-go (seconds to goals around its end through the graph); returns the modb.graphs id. Rebuild after loading';

-- A transition graph's level-0 transitions, stored. From a kept snippet, select_next_snippet reads its
-- successors here (one index lookup, then the exact check of a few dozen rows) instead of searching the
-- feature box (which admits hundreds to thousands of candidates in dense data, each checked exactly).
-- Valid only for the continuity settings the graph was built with: modb.transition_key says which.

CREATE TABLE modb.graph_transitions (
    graph_id     bigint NOT NULL,
    from_snippet bigint NOT NULL,
    to_snippets  bigint[] NOT NULL,
    cost_to_go   real[],
    PRIMARY KEY (graph_id, from_snippet),
    FOREIGN KEY (graph_id, from_snippet) REFERENCES modb.graph_snippets ON DELETE CASCADE
);
COMMENT ON TABLE modb.graph_transitions IS
    'For each snippet a transition graph keeps: the kept snippets that may follow it at relaxation level 0 (a superset by a hair: the exact test runs again at selection). One row per snippet, not per transition: a tenth of the size';
SELECT pg_catalog.pg_extension_config_dump('modb.graph_transitions', '');

CREATE OR REPLACE FUNCTION modb.transition_key(plan modb.match_plan)
RETURNS jsonb
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- The settings that decide which transitions pass level 0; the objective's weights do not.
RETURN jsonb_build_object('joints', (plan).joints, 'norm', (plan).norm, 'velocity_terms', (plan).velocity_terms,
                          'position_threshold', (plan).position_threshold, 'angle_threshold', (plan).angle_threshold,
                          'velocity_threshold', (plan).velocity_threshold,
                          'angular_velocity_threshold', (plan).angular_velocity_threshold);
COMMENT ON FUNCTION modb.transition_key(modb.match_plan) IS
    'What a plan''s level-0 test depends on (joints, norm, velocity terms, thresholds): a graph''s stored transitions serve the plans with its key';

-- Graph names, in a table no selection reads: a graph is deleted by deleting its name here, and its
-- modb.graphs row, stored snippets and transitions go with it (ON DELETE CASCADE, run as the owner). So the
-- loader needs no DELETE on modb.graphs, which every selection reads (a DELETE grant would also let it LOCK
-- that table against every reader).
CREATE TABLE modb.graph_names (
    name text NOT NULL,
    kind text NOT NULL,
    PRIMARY KEY (name, kind)
);
COMMENT ON TABLE modb.graph_names IS
    'The name and kind of every graph in modb.graphs: deleting a row here deletes that graph with its rows';
INSERT INTO modb.graph_names (name, kind) SELECT name, kind FROM modb.graphs;  -- on update: the graphs so far
ALTER TABLE modb.graphs ADD FOREIGN KEY (name, kind) REFERENCES modb.graph_names ON DELETE CASCADE;
SELECT pg_catalog.pg_extension_config_dump('modb.graph_names', '');

GRANT SELECT ON modb.graph_names TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_names TO modb_loader;
GRANT INSERT (name, kind, skeleton_id, data, meta) ON modb.graphs TO modb_loader;
GRANT UPDATE (skeleton_id, data, meta) ON modb.graphs TO modb_loader;
