-- 0.5.0: a transition graph stores its level-0 transitions (modb.graph_transitions); select_next_snippet
-- reads prev's successors there instead of searching the feature box. Graphs built by 0.4.0 have none
-- stored and keep working through the box: rebuild them (modb.build_transition_graph) for the speed.
--@include 75_graphs_transitions.sql
--@include 76_select.sql
GRANT SELECT ON modb.graph_transitions TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_transitions TO modb_loader;
