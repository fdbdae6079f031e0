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
