-- A match profile resolved for one query (modb.match_plan, built by 79_match_plan.sql), the session's
-- knobs it reads, and its thresholds per joint.

CREATE TYPE modb.match_plan AS (
    joints                     int[],
    position_threshold         float8[],
    angle_threshold            float8[],
    velocity_threshold         float8[],
    angular_velocity_threshold float8[],
    norm                       text,
    velocity_terms             boolean,
    heading_weight             float8,
    box_half_width             float8[],
    continuity_weight          float8,
    lookahead_distance         float8,
    graph_id                   bigint,
    graph_lookahead            boolean,
    graph_cost_to_go           boolean,
    annotations                text[]
);
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, whether it ranks by the graph''s cost-to-go, and the annotation names candidates keep to (modb.annotation_spec), if any';

CREATE FUNCTION modb.session_settings()
RETURNS text[]
LANGUAGE c STABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_session_settings';
COMMENT ON FUNCTION modb.session_settings() IS
    'Names of this session''s modb.* settings that have a value (pg_settings does not list them: they are placeholders)';

CREATE FUNCTION modb._thresholds(spec jsonb, joints text[], included text[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
BEGIN ATOMIC
    SELECT array_agg(CASE WHEN j <> ALL (included) THEN 'Infinity'::float8
                          WHEN jsonb_typeof(spec) = 'number' THEN spec::text::float8
                          ELSE coalesce((spec->>j)::float8, (spec->>'default')::float8) END ORDER BY n)
      FROM unnest(joints) WITH ORDINALITY AS t(j, n);
END;
COMMENT ON FUNCTION modb._thresholds(jsonb, text[], text[]) IS
    'Internal: a threshold per joint from a number or {"default": x, "<joint>": y}; Infinity for joints not included';
