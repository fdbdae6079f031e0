-- 0.4.0: transition graphs. modb.build_transition_graph keeps the snippets a chain can keep moving and
-- steering among (the largest strongly connected component of level-0 transitions that turns both ways); the `graph`
-- knob restricts select_next_snippet (and modb.synthesize) to them, so chains no longer run into dead
-- ends. The objective scores the nearer of a candidate's end and where it leads (modb.approach_cost).

ALTER TYPE modb.match_plan ADD ATTRIBUTE graph_id bigint;
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, and the transition graph (modb.graphs id) candidates must belong to, if any';
--@include 75_graphs.sql
--@include 72_plan.sql
--@include 76_select.sql
-- synthesize runs without JIT (its steps' generic plans passed jit_above_cost and compiled for seconds each)
-- and checks every request first.
--@include 78_synthesize.sql
GRANT SELECT ON modb.graph_snippets TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_snippets TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) TO modb_loader;
