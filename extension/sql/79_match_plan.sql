-- Resolving a match profile (with a session's SET modb.<knob> overrides) into a modb.match_plan.
-- CREATE OR REPLACE: upgrades include this file when the plan changes.

CREATE OR REPLACE FUNCTION modb.match_knobs()
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY['joints', 'norm', 'position_threshold', 'angle_threshold', 'velocity_threshold',
             'angular_velocity_threshold', 'velocity_terms', 'heading_weight', 'continuity_weight', 'lookahead_distance',
             'graph', 'graph_lookahead', 'graph_cost_to_go'];
COMMENT ON FUNCTION modb.match_knobs() IS 'Settings a session may override with SET modb.<knob> = ...';

CREATE OR REPLACE FUNCTION modb.match_plan(profile text)
RETURNS modb.match_plan
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    settings jsonb;
    knob text;
    value text;
    unknown text;
    plan modb.match_plan;
    names text[] := modb.standard_joints();
    features text[] := modb.feature_names();
    joint_names text[];
    position_by_joint float8[];
    velocity_by_joint float8[];
    included boolean[];
    feature text;
    joint text;
    s int;
BEGIN
    SELECT p.settings INTO settings FROM modb.match_profiles p WHERE p.name = coalesce(profile, 'default');
    IF NOT FOUND THEN
        RAISE EXCEPTION 'unknown match profile "%"', profile
            USING HINT = 'profiles: ' || (SELECT string_agg(name, ', ' ORDER BY name) FROM modb.match_profiles);
    END IF;
    SELECT string_agg(name, ', ') INTO unknown
      FROM unnest(modb.session_settings()) AS name WHERE substr(name, 6) <> ALL (modb.match_knobs());
    IF unknown IS NOT NULL THEN
        RAISE EXCEPTION 'unknown modb setting: %', unknown
            USING HINT = 'knobs are modb.' || array_to_string(modb.match_knobs(), ', modb.') || '; RESET the unknown one';
    END IF;
    FOREACH knob IN ARRAY modb.match_knobs() LOOP
        value := nullif(current_setting('modb.' || knob, true), '');
        CONTINUE WHEN value IS NULL;
        settings := settings || jsonb_build_object(knob, CASE
            WHEN knob = 'joints' THEN to_jsonb(string_to_array(replace(value, ' ', ''), ','))
            WHEN knob = 'norm' THEN to_jsonb(lower(value))
            WHEN knob = 'graph' THEN to_jsonb(value)
            WHEN knob IN ('velocity_terms', 'graph_lookahead', 'graph_cost_to_go') THEN to_jsonb(value::boolean)
            WHEN knob LIKE '%threshold' THEN jsonb_build_object('default', value::float8)  -- one value for every joint
            ELSE to_jsonb(value::float8) END);
    END LOOP;
    joint_names := ARRAY(SELECT jsonb_array_elements_text(settings->'joints'));
    IF joint_names = '{}' OR EXISTS (SELECT FROM unnest(joint_names) j WHERE j <> ALL (names)) THEN
        RAISE EXCEPTION 'profile "%": joints % must be standard joints', profile, joint_names
            USING HINT = 'standard joints: ' || array_to_string(names, ', ');
    END IF;
    IF EXISTS (SELECT FROM jsonb_each(settings) AS e(k, v)
                WHERE k LIKE '%threshold'
                  AND EXISTS (SELECT FROM jsonb_path_query(v, 'strict $.** ? (@.type() == "number")') AS x(n)
                              WHERE NOT (x.n::text::float8 > 0))) THEN
        RAISE EXCEPTION 'profile "%": thresholds must be positive', profile
            USING HINT = 'check SET modb.*_threshold and the profile''s settings';
    END IF;
    IF coalesce((settings->>'heading_weight')::float8, 0) < 0 THEN
        RAISE EXCEPTION 'profile "%": heading_weight must not be negative', profile;
    END IF;
    IF coalesce((settings->>'continuity_weight')::float8, 0) < 0 THEN
        RAISE EXCEPTION 'profile "%": continuity_weight must not be negative', profile;
    END IF;
    IF NOT coalesce((settings->>'lookahead_distance')::float8, 1) > 0 THEN
        RAISE EXCEPTION 'profile "%": lookahead_distance must be positive (or absent: score against the goal itself)', profile;
    END IF;
    plan.norm := coalesce(settings->>'norm', 'l2');
    IF plan.norm NOT IN ('l1', 'l2') THEN
        RAISE EXCEPTION 'norm must be l1 or l2, not "%"', plan.norm;
    END IF;
    plan.velocity_terms := coalesce((settings->>'velocity_terms')::boolean, true);
    plan.heading_weight := coalesce((settings->>'heading_weight')::float8, 0);
    plan.continuity_weight := coalesce((settings->>'continuity_weight')::float8, 0);
    plan.lookahead_distance := (settings->>'lookahead_distance')::float8;
    plan.graph_lookahead := coalesce((settings->>'graph_lookahead')::boolean, false);
    plan.graph_cost_to_go := coalesce((settings->>'graph_cost_to_go')::boolean, true);
    IF settings ? 'graph' THEN
        SELECT g.id INTO plan.graph_id FROM modb.graphs g WHERE g.name = settings->>'graph' AND g.kind = 'transitions';
        IF NOT FOUND THEN
            RAISE EXCEPTION 'no transition graph "%"', settings->>'graph'
                USING HINT = 'build it with modb.build_transition_graph(''' || (settings->>'graph') || ''') or `modb graph build`';
        END IF;
    END IF;
    plan.joints := ARRAY(SELECT array_position(names, j) - 1 FROM unnest(joint_names) WITH ORDINALITY t(j, n) ORDER BY n);
    plan.position_threshold := modb._thresholds(settings->'position_threshold', names, joint_names);
    plan.angle_threshold := modb._thresholds(settings->'angle_threshold', names, joint_names);
    plan.velocity_threshold := modb._thresholds(settings->'velocity_threshold', names, joint_names);
    plan.angular_velocity_threshold := modb._thresholds(settings->'angular_velocity_threshold', names, joint_names);
    position_by_joint := plan.position_threshold;
    velocity_by_joint := plan.velocity_threshold;
    -- Box half-widths: a feature of an included joint gets that joint's threshold (an L1 or L2 ball
    -- lies inside the box of its radius, so the box loses no candidate); the others are unbounded. A
    -- rotation-matrix entry moves by at most 2 sin(angle / 2) (R e - R' e is a chord of the unit sphere),
    -- and 2 sin(s x / 2) <= s x 2 sin(x / 2) for the relaxation scales s >= 1, so scaling the box stays exact.
    plan.box_half_width := '{}';
    FOREACH feature IN ARRAY features LOOP
        joint := split_part(feature, '.', 1);
        s := array_position(names, joint);
        plan.box_half_width := plan.box_half_width || CASE
            WHEN joint <> ALL (joint_names) THEN 1e6::float8  -- unbounded, without infinities in the cube
            WHEN split_part(feature, '.', 2) LIKE 'v_' THEN
                CASE WHEN plan.velocity_terms THEN velocity_by_joint[s] ELSE 1e6::float8 END
            WHEN split_part(feature, '.', 2) LIKE 'R__' THEN 2 * sin(least(plan.angle_threshold[s], pi()) / 2)
            ELSE position_by_joint[s] END;
    END LOOP;
    RETURN plan;
END
$$;
COMMENT ON FUNCTION modb.match_plan(text) IS
    'Resolves a match profile with this session''s SET modb.<knob> overrides; an unknown profile or knob is an error';
