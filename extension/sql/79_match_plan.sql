-- Resolving a match profile (with a session's SET modb.<knob> overrides) into a modb.match_plan.
-- CREATE OR REPLACE: upgrades include this file when the plan changes.

CREATE OR REPLACE FUNCTION modb.match_knobs()
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY['joints', 'norm', 'position_threshold', 'angle_threshold', 'velocity_threshold',
             'angular_velocity_threshold', 'velocity_terms', 'heading_weight', 'continuity_weight', 'lookahead_distance',
             'graph', 'graph_lookahead', 'graph_cost_to_go', 'annotations'];
COMMENT ON FUNCTION modb.match_knobs() IS 'Settings a session may override with SET modb.<knob> = ...';

-- The ranges of the numeric knobs, checked at every selection (the knobs are placeholder settings, which
-- PostgreSQL stores as text whatever they hold): thresholds and lookahead_distance 1e-300 to 1e300,
-- weights 0 or 1e-300 to 1e300. Finite, and far from where float8 overflows or underflows: a threshold
-- is multiplied by 8 (relaxation) and divided into differences.
CREATE OR REPLACE FUNCTION modb._knob_number(knob text, value text, origin text)
RETURNS float8
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
DECLARE
    positive boolean := knob LIKE '%threshold' OR knob = 'lookahead_distance';  -- else 0 is allowed too
    n numeric;
    rule text;
    allowed text;
    unit text;
BEGIN
    -- A decimal number (what float8 reads, without NaN and the infinities); numeric holds any of them exactly.
    IF value ~ '^\s*[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]{1,4})?\s*$' THEN
        n := value::numeric;
        IF (n = 0 AND NOT positive) OR n BETWEEN 1e-300 AND 1e300 THEN
            RETURN n::float8;
        END IF;
    END IF;
    unit := CASE knob WHEN 'position_threshold' THEN 'metres' WHEN 'angle_threshold' THEN 'radians'
                      WHEN 'velocity_threshold' THEN 'm/s' WHEN 'angular_velocity_threshold' THEN 'rad/s'
                      WHEN 'heading_weight' THEN 'metres per radian'
                      WHEN 'continuity_weight' THEN 'metres per unit of continuity ratio'
                      WHEN 'lookahead_distance' THEN 'metres' END;
    rule := CASE WHEN knob LIKE '%threshold' THEN 'thresholds must be positive and finite'
                 WHEN knob = 'lookahead_distance'
                 THEN 'lookahead_distance must be positive and finite, or absent to score against the goal itself'
                 ELSE knob || ' must not be negative and must be finite' END;
    allowed := CASE WHEN positive THEN '1e-300 to 1e300 ' ELSE '0, or 1e-300 to 1e300 ' END || unit;
    RAISE EXCEPTION '% = % is %: % (allowed: %)',
        coalesce(origin, 'modb.' || knob), coalesce(quote_literal(value), 'null'),
        CASE WHEN n IS NULL THEN 'not a finite number' ELSE 'out of range' END, rule, allowed
        USING HINT = CASE WHEN origin IS NULL
            THEN format('SET modb.%s to a number in the allowed range, or RESET modb.%s for the profile''s value', knob, knob)
            ELSE 'correct the profile''s settings in modb.match_profiles, or override them with SET modb.' || knob END;
END
$$;
COMMENT ON FUNCTION modb._knob_number(text, text, text) IS
    'Internal: a numeric knob''s value (the text of SET modb.<knob> or of a profile''s setting) as float8, or an error naming the knob (origin: where in a profile, NULL for SET), the value and the allowed range';

CREATE OR REPLACE FUNCTION modb._knob_boolean(knob text, value text, origin text)
RETURNS boolean
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
BEGIN
    -- What boolean input reads (PostgreSQL accepts unique prefixes of true, false, yes and no).
    IF lower(btrim(value)) ~ '^(t|tr|tru|true|f|fa|fal|fals|false|y|ye|yes|n|no|on|of|off|1|0)$' THEN
        RETURN btrim(value)::boolean;
    END IF;
    RAISE EXCEPTION '% = % is not a boolean (allowed: on or off)',
        coalesce(origin, 'modb.' || knob), coalesce(quote_literal(value), 'null')
        USING HINT = CASE WHEN origin IS NULL
            THEN format('SET modb.%s = on (or off), or RESET modb.%s for the profile''s value', knob, knob)
            ELSE 'correct the profile''s settings in modb.match_profiles, or override them with SET modb.' || knob END;
END
$$;
COMMENT ON FUNCTION modb._knob_boolean(text, text, text) IS
    'Internal: a boolean knob''s value (the text of SET modb.<knob> or of a profile''s setting), or an error naming the knob (origin: where in a profile, NULL for SET) and the value';

CREATE OR REPLACE FUNCTION modb.match_plan(profile text)
RETURNS modb.match_plan
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    settings jsonb;
    knob text;
    value text;
    unknown text;
    session_knobs text[] := '{}';  -- the knobs this session SETs (checked as they are read)
    plan modb.match_plan;
    names text[] := modb.standard_joints();
    features text[] := modb.feature_names();
    joint_names text[];
    position_by_joint float8[];
    velocity_by_joint float8[];
    spec jsonb;
    entry record;
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
    -- The session's knobs, each checked against its range as it is read (README "Knobs"): the knobs are
    -- placeholder settings, text whatever they hold, so 'Infinity', 'NaN' or '1e999' get this far.
    FOREACH knob IN ARRAY modb.match_knobs() LOOP
        value := current_setting('modb.' || knob, true);
        value := CASE WHEN lower(btrim(value)) NOT IN ('', 'profile') THEN value END;  -- '' or profile: the profile's
        CONTINUE WHEN value IS NULL;
        session_knobs := session_knobs || knob;
        settings := settings || jsonb_build_object(knob, CASE
            WHEN knob = 'joints' THEN to_jsonb(string_to_array(replace(value, ' ', ''), ','))
            WHEN knob = 'norm' THEN to_jsonb(lower(btrim(value)))
            WHEN knob = 'graph' THEN to_jsonb(value)
            WHEN knob = 'annotations' THEN coalesce(to_jsonb(modb.annotation_spec(value)), '[]')
            WHEN knob IN ('velocity_terms', 'graph_lookahead', 'graph_cost_to_go') THEN to_jsonb(modb._knob_boolean(knob, value, NULL))
            WHEN knob LIKE '%threshold' THEN jsonb_build_object('default', modb._knob_number(knob, value, NULL))  -- one value for every joint
            ELSE to_jsonb(modb._knob_number(knob, value, NULL)) END);
    END LOOP;
    -- The profile's own values, in the same ranges.
    FOREACH knob IN ARRAY ARRAY['position_threshold', 'angle_threshold', 'velocity_threshold', 'angular_velocity_threshold'] LOOP
        CONTINUE WHEN knob = ANY (session_knobs);
        spec := settings->knob;
        IF jsonb_typeof(spec) = 'object' THEN
            FOR entry IN SELECT e.key, e.value FROM jsonb_each(spec) AS e WHERE e.value <> 'null' LOOP  -- null: the default
                PERFORM modb._knob_number(knob, entry.value #>> '{}', format('profile "%s": %s of %s', profile, knob, entry.key));
            END LOOP;
        ELSIF spec IS NOT NULL THEN
            PERFORM modb._knob_number(knob, spec #>> '{}', format('profile "%s": %s', profile, knob));
        END IF;
    END LOOP;
    FOREACH knob IN ARRAY ARRAY['heading_weight', 'continuity_weight', 'lookahead_distance'] LOOP
        CONTINUE WHEN knob = ANY (session_knobs) OR settings->>knob IS NULL;  -- absent or null: the default
        PERFORM modb._knob_number(knob, settings->>knob, format('profile "%s": %s', profile, knob));
    END LOOP;
    FOREACH knob IN ARRAY ARRAY['velocity_terms', 'graph_lookahead', 'graph_cost_to_go'] LOOP
        CONTINUE WHEN knob = ANY (session_knobs) OR settings->>knob IS NULL;  -- absent or null: the default
        PERFORM modb._knob_boolean(knob, settings->>knob, format('profile "%s": %s', profile, knob));
    END LOOP;
    IF jsonb_typeof(settings->'joints') IS DISTINCT FROM 'array' THEN
        RAISE EXCEPTION 'profile "%": joints must be a list of standard joints, got %', profile, coalesce(settings->>'joints', 'none')
            USING HINT = 'standard joints: ' || array_to_string(names, ', ');
    END IF;
    joint_names := ARRAY(SELECT jsonb_array_elements_text(settings->'joints'));
    IF joint_names = '{}' OR EXISTS (SELECT FROM unnest(joint_names) j WHERE j IS NULL OR j <> ALL (names)) THEN
        RAISE EXCEPTION '%: joints % must be standard joints',
            CASE WHEN 'joints' = ANY (session_knobs) THEN format('modb.joints = %L', current_setting('modb.joints'))
                 ELSE format('profile "%s"', profile) END, joint_names
            USING HINT = 'standard joints: ' || array_to_string(names, ', ');
    END IF;
    plan.norm := coalesce(settings->>'norm', 'l2');
    IF plan.norm NOT IN ('l1', 'l2') THEN
        RAISE EXCEPTION '%: norm must be l1 or l2, not "%"',
            CASE WHEN 'norm' = ANY (session_knobs) THEN 'modb.norm' ELSE format('profile "%s"', profile) END, plan.norm
            USING HINT = 'SET modb.norm = l1 (or l2), or RESET modb.norm for the profile''s';
    END IF;
    plan.velocity_terms := coalesce((settings->>'velocity_terms')::boolean, true);
    plan.heading_weight := coalesce((settings->>'heading_weight')::float8, 0);
    plan.continuity_weight := coalesce((settings->>'continuity_weight')::float8, 0);
    plan.lookahead_distance := (settings->>'lookahead_distance')::float8;
    plan.graph_lookahead := coalesce((settings->>'graph_lookahead')::boolean, false);
    plan.graph_cost_to_go := coalesce((settings->>'graph_cost_to_go')::boolean, true);
    plan.annotations := CASE jsonb_typeof(settings->'annotations')  -- a profile's: a list or 'walk, !run'
        WHEN 'array' THEN modb.annotation_spec(array_to_string(ARRAY(SELECT jsonb_array_elements_text(settings->'annotations')), ','),
                                               format('profile "%s": annotations', profile))
        WHEN 'string' THEN modb.annotation_spec(settings->>'annotations', format('profile "%s": annotations', profile))
        END;
    IF settings ? 'graph' AND lower(btrim(settings->>'graph')) <> 'none' THEN  -- 'none': no graph
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
    -- Every joint compared needs each threshold: its own, or the profile's "default".
    SELECT string_agg(t.knob || ' of ' || names[j.i + 1], ', ') INTO unknown
      FROM unnest(plan.joints) AS j(i)
     CROSS JOIN LATERAL (VALUES ('position_threshold', plan.position_threshold[j.i + 1]),
                                ('angle_threshold', plan.angle_threshold[j.i + 1]),
                                ('velocity_threshold', plan.velocity_threshold[j.i + 1]),
                                ('angular_velocity_threshold', plan.angular_velocity_threshold[j.i + 1])) AS t(knob, x)
     WHERE t.x IS NULL;
    IF unknown IS NOT NULL THEN
        RAISE EXCEPTION 'profile "%" has no %: thresholds must be positive and finite for every joint it compares', profile, unknown
            USING HINT = 'give each threshold a "default" in the profile''s settings, or SET modb.<threshold> for every joint';
    END IF;
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
