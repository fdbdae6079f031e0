-- 0.6.0: a transition graph stores each snippet's cost-to-go (seconds to goals around its end through the
-- graph), and select_next_snippet's stored-transition level ranks by it (knob graph_cost_to_go, on by
-- default). Graphs built by 0.5.0 have none and rank as before: rebuild them (modb.build_transition_graph).
-- The shipped default profile's continuity_weight goes from 0.3 to 0.6.
ALTER TYPE modb.match_plan ADD ATTRIBUTE graph_cost_to_go boolean;
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, and whether it ranks by the graph''s cost-to-go';
ALTER TABLE modb.graph_transitions ADD COLUMN cost_to_go real[];
--@include 75_graphs_transitions_cost_to_go.sql
--@include 72_plan.sql
--@include 76_select.sql
--@include 73_profiles.sql
