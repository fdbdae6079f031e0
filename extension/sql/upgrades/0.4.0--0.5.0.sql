-- 0.5.0: a transition graph stores its level-0 transitions (modb.graph_transitions); select_next_snippet
-- reads prev's successors there instead of searching the feature box, and with the graph_lookahead knob
-- scores a candidate also by the best snippet that may follow it. Graphs built by 0.4.0 have no stored
-- transitions and keep working through the box: rebuild them (modb.build_transition_graph).
ALTER TYPE modb.match_plan ADD ATTRIBUTE graph_lookahead boolean;
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, and whether the objective looks one snippet further through it';
--@include 75_graphs_transitions.sql
--@include 72_plan.sql
--@include 76_select.sql
GRANT SELECT ON modb.graph_transitions TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_transitions TO modb_loader;
