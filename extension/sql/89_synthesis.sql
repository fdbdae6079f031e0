-- synthesize: a whole chain of snippets toward a queue of world goals, in one recursive query, so any SQL
-- client can synthesize. The Python Avatar (client/modb/avatar.py) follows the same rules step for step;
-- with lead time zero both give the same chain (tested).
--
-- Rules: the avatar stands at a ground point with a heading. A snippet is placed with its first frame on
-- that point and heading; at its end the avatar has moved by net_translation (x, z; in the heading frame)
-- and turned by net_heading. A goal is reached when the pelvis is within arrival_radius of it (on the
-- ground) at a snippet's end; the next choice then serves the next goal, and after the last goal the
-- avatar keeps serving the last one. Snippets whose play ended less than exclude_seconds before the end of
-- the current one are passed as exclude. Time is counted in frames (the chain has one rate), so both
-- paths compare the same integers. When nothing can follow, the chain ends (the Avatar raises NoContinuation
-- there, and modb synth stops the strip and says so). CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.local_to_world(origin float8[], heading float8, local_point float8[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- The inverse of world_to_local: x left and z forward of a character at origin facing heading.
RETURN CASE WHEN array_length(local_point, 1) = 3
    THEN ARRAY[origin[1] + (local_point[1] * cos(heading) + local_point[3] * sin(heading)),
               origin[2] + local_point[2],
               origin[3] + (local_point[3] * cos(heading) - local_point[1] * sin(heading))]
    ELSE ARRAY[origin[1] + (local_point[1] * cos(heading) + local_point[2] * sin(heading)),
               origin[3] + (local_point[2] * cos(heading) - local_point[1] * sin(heading))] END;
COMMENT ON FUNCTION modb.local_to_world(float8[], float8, float8[]) IS
    'A point given in the heading frame of a character at origin {x, y, z} with heading theta ({x, z} or {x, y, z}; x left, z forward) in world coordinates';

CREATE OR REPLACE FUNCTION modb.synthesis_goal(targets float8[], goal int)
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN CASE array_length(targets, 2) WHEN 2 THEN ARRAY[targets[goal][1], targets[goal][2]]
            ELSE ARRAY[targets[goal][1], targets[goal][2], targets[goal][3]] END;
COMMENT ON FUNCTION modb.synthesis_goal(float8[], int) IS
    'Row goal (1-based) of a synthesize targets array, as a {x, z} or {x, y, z} world point';

CREATE OR REPLACE FUNCTION modb.synthesis_step_end(origin float8[], heading float8, net_translation float8[], net_heading float8,
                                        target float8[], arrival_radius float8)
RETURNS TABLE (end_position float8[], end_heading float8, reached boolean)
LANGUAGE sql IMMUTABLE PARALLEL SAFE
AS $$
SELECT w.p, atan2(sin(heading + net_heading), cos(heading + net_heading)),
       sqrt((w.p[1] - target[1]) * (w.p[1] - target[1])
            + (w.p[3] - target[array_length(target, 1)]) * (w.p[3] - target[array_length(target, 1)])) <= arrival_radius
  FROM (SELECT modb.local_to_world(origin, heading, ARRAY[net_translation[1], 0, net_translation[3]]) AS p) w
$$;
COMMENT ON FUNCTION modb.synthesis_step_end(float8[], float8, float8[], float8, float8[], float8) IS
    'Where a snippet placed at origin/heading leaves the avatar (its ground travel and turn), and whether the pelvis is then within arrival_radius of target on the ground';

CREATE OR REPLACE FUNCTION modb.check_synthesis(targets float8[], max_snippets int, start_snippet bigint,
                                     start_position float8[], start_heading float8, profile text,
                                     arrival_radius float8, exclude_seconds float8)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    -- Coordinates: finite, within 1e9 m (as select_next_snippet's targets); subscripts from 1, as written.
    -- NaN is above every number, so NOT (abs(v) <= 1e9) and NOT (v > 0) hold for it too.
    IF targets IS NULL OR array_ndims(targets) IS DISTINCT FROM 2 OR array_length(targets, 2) NOT IN (2, 3)
       OR array_lower(targets, 1) <> 1 OR array_lower(targets, 2) <> 1
       OR EXISTS (SELECT FROM unnest(targets) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'targets must be a list of world goals {{x, z}, ...} or {{x, y, z}, ...} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(targets::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF max_snippets IS NULL OR max_snippets < 1 THEN
        RAISE EXCEPTION 'max_snippets must be at least 1, got %', coalesce(max_snippets::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_position IS NULL OR array_ndims(start_position) IS DISTINCT FROM 1 OR array_length(start_position, 1) <> 3
       OR array_lower(start_position, 1) <> 1
       OR EXISTS (SELECT FROM unnest(start_position) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'start_position must be {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(start_position::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_heading IS NULL OR NOT abs(start_heading) < 'Infinity' THEN
        RAISE EXCEPTION 'start_heading must be a finite angle in radians (0 faces +Z), got %',
            coalesce(start_heading::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF arrival_radius IS NULL OR NOT arrival_radius > 0 OR NOT arrival_radius < 'Infinity' THEN
        RAISE EXCEPTION 'arrival_radius must be a positive, finite number of metres, got %', coalesce(arrival_radius::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF exclude_seconds IS NULL OR NOT exclude_seconds >= 0 OR NOT exclude_seconds < 'Infinity' THEN
        RAISE EXCEPTION 'exclude_seconds must be zero or more (a finite number of seconds), got %', coalesce(exclude_seconds::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = start_snippet) THEN
        RAISE EXCEPTION 'no snippet %', start_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'start_snippet is a modb.snippets id, or NULL for the snippet that best serves the first goal';
    END IF;
    PERFORM modb.match_plan(profile);  -- an unknown profile fails here even when no selection runs
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_synthesis(float8[], int, bigint, float8[], float8, text, float8, float8) IS
    'Raises a clear error for a synthesize request that cannot be run (bad targets, sizes, start or profile)';

CREATE OR REPLACE FUNCTION modb.synthesis_chain(targets float8[], max_snippets int, start_snippet bigint,
                                     start_position float8[], start_heading float8,
                                     profile text, collection text,
                                     arrival_radius float8, exclude_seconds float8, can_rest boolean)
RETURNS TABLE (step int, snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int,
               n_frames int, fps float8, start_time float8, "position" float8[], heading float8,
               end_position float8[], end_heading float8, goal int, target float8[], reached boolean,
               relax_level int, continuity float8, proximity float8)
LANGUAGE sql STABLE PARALLEL SAFE
-- Each step runs select_next_snippet_world as a function with a generic plan, whose estimate (it keeps the
-- opening branch's full scan) passes jit_above_cost: JIT then compiled for ~9 s per step, against ~0.15 s
-- of work. A SET clause keeps synthesize from being inlined, which gains nothing for one recursive query.
SET jit = off
AS $$
WITH RECURSIVE cfg AS MATERIALIZED (
    SELECT modb.check_synthesis(targets, max_snippets, start_snippet, start_position, start_heading, profile,
                                arrival_radius, exclude_seconds) AS ok,
           array_length(targets, 1) AS n_goals
), opening AS (
    -- The given start snippet, or the one that best serves the first goal.
    SELECT s.id AS snippet_id, NULL::int AS relax_level, NULL::float8 AS continuity, NULL::float8 AS proximity
      FROM modb.snippets s
     WHERE s.id = start_snippet AND (SELECT ok FROM cfg)
    UNION ALL
    SELECT n.snippet_id, n.relax_level, n.continuity, n.proximity
      FROM modb.select_next_snippet_world(NULL, start_position, start_heading, modb.synthesis_goal(targets, 1),
                                          profile, collection) n
     WHERE start_snippet IS NULL AND (SELECT ok FROM cfg)
), chain AS (
    SELECT 0 AS step, s.id AS snippet_id, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, s.fps,
           0 AS start_frame, s.n_frames - 1 AS end_frame, start_position AS "position", start_heading AS heading,
           e.end_position, e.end_heading, 1 AS goal, g.target, e.reached, o.relax_level, o.continuity, o.proximity,
           ARRAY(SELECT s.id WHERE 0 < exclude_seconds * s.fps) AS recent_ids,
           ARRAY(SELECT s.n_frames - 1 WHERE 0 < exclude_seconds * s.fps) AS recent_ends,
           e.reached AND (SELECT n_goals FROM cfg) = 1 AS resting  -- the last goal reached: come to rest
      FROM opening o
      JOIN modb.snippets s ON s.id = o.snippet_id
     CROSS JOIN LATERAL (SELECT modb.synthesis_goal(targets, 1) AS target) g
     CROSS JOIN LATERAL modb.synthesis_step_end(start_position, start_heading, s.net_translation, s.net_heading,
                                                g.target, arrival_radius) e
    UNION ALL
    SELECT c.step + 1, s.id, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, s.fps,
           c.end_frame, f.end_frame, c.end_position, c.end_heading,
           e.end_position, e.end_heading, g.goal, g.target, e.reached, n.relax_level, n.continuity, n.proximity,
           k.ids, k.ends, c.resting OR (e.reached AND g.goal = (SELECT n_goals FROM cfg))
      FROM chain c
     CROSS JOIN LATERAL (SELECT CASE WHEN c.reached AND c.goal < (SELECT n_goals FROM cfg) THEN c.goal + 1
                                     ELSE c.goal END AS goal) gi
     CROSS JOIN LATERAL (SELECT gi.goal, modb.synthesis_goal(targets, gi.goal) AS target) g
     CROSS JOIN LATERAL modb.select_synthesis_step(c.snippet_id, c.end_position, c.end_heading, g.target,
                                                   profile, collection, c.recent_ids, c.resting AND can_rest) n
      JOIN modb.snippets s ON s.id = n.snippet_id
     CROSS JOIN LATERAL modb.synthesis_step_end(c.end_position, c.end_heading, s.net_translation, s.net_heading,
                                                g.target, arrival_radius) e
     CROSS JOIN LATERAL (SELECT c.end_frame + s.n_frames - 1 AS end_frame) f
     CROSS JOIN LATERAL (  -- the snippets played within exclude_seconds of this one's end (itself included)
         SELECT coalesce(array_agg(r.id), '{}') AS ids, coalesce(array_agg(r.e), '{}') AS ends
           FROM unnest(c.recent_ids || s.id, c.recent_ends || f.end_frame) AS r(id, e)
          WHERE f.end_frame - r.e < exclude_seconds * s.fps) k
     WHERE c.step + 1 < max_snippets
)
SELECT step, snippet_id, clip_id, version, mirrored, first_frame, n_frames, fps, start_frame / fps,
       "position", heading, end_position, end_heading, goal, target, reached, relax_level, continuity, proximity
  FROM chain
 WHERE (SELECT ok FROM cfg)  -- a one-time filter, run first: bad requests raise even when no snippet matches
$$;
COMMENT ON FUNCTION modb.synthesis_chain(float8[], int, bigint, float8[], float8, text, text, float8, float8, boolean) IS
    'modb.synthesize''s chain under the session''s settings as they are (synthesize chooses the collection and graph first, and whether it can come to rest: modb.can_rest): a chain of up to max_snippets snippets from start_position/start_heading (world metres, radians; 0 faces +Z) through the world goals in targets ({{x, z}, ...} or {{x, y, z}, ...}), in order: one row per snippet with where it is placed, where it ends, the goal it served and whether it reached it (pelvis within arrival_radius on the ground), and its selection (relaxation level, continuity, proximity). Its first frame stands in for the previous snippet''s last; start_time is the time of that frame. The chain ends early when nothing can follow (every candidate excluded)';

CREATE OR REPLACE FUNCTION modb.synthesize(targets float8[], max_snippets int, start_snippet bigint DEFAULT NULL,
                                start_position float8[] DEFAULT '{0,0,0}', start_heading float8 DEFAULT 0,
                                profile text DEFAULT 'default', collection text DEFAULT NULL,
                                arrival_radius float8 DEFAULT 0.5, exclude_seconds float8 DEFAULT 2,
                                annotations text DEFAULT NULL)
RETURNS TABLE (step int, snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int,
               n_frames int, fps float8, start_time float8, "position" float8[], heading float8,
               end_position float8[], end_heading float8, goal int, target float8[], reached boolean,
               relax_level int, continuity float8, proximity float8)
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE  -- it SETs modb.graph (transaction-local) for its own selections
SET jit = off
AS $$
DECLARE
    knob text := current_setting('modb.graph', true);
    annotations_knob text := current_setting('modb.annotations', true);
    pool record;
    graph text;
BEGIN
    -- Without a collection or start: the largest skeleton-and-rate pool (a chain never mixes them).
    IF collection IS NULL AND start_snippet IS NULL THEN
        SELECT p.*, count(*) OVER () AS pools INTO pool FROM modb.snippet_pools() p LIMIT 1;
        collection := pool.collection;
        IF pool.pools > 1 THEN
            RAISE NOTICE 'modb: synthesizing from %: the largest skeleton-and-rate pool (% snippets at % fps)',
                coalesce('collection ' || pool.collection, 'every collection'), pool.snippets, pool.fps
                USING HINT = 'pass collection (or start_snippet) to choose';
        END IF;
    END IF;
    -- Without a graph named by the session (or the profile): the newest current one over that data, so the
    -- chain keeps to snippets it can keep moving and steering among. SET modb.graph = 'none' for the
    -- paper's plain rule.
    IF coalesce(lower(btrim(knob)), '') IN ('', 'profile')
       AND NOT coalesce((SELECT p.settings ? 'graph' FROM modb.match_profiles p WHERE p.name = profile), false) THEN
        graph := modb.default_graph(profile, collection);
        IF graph IS NULL THEN
            RAISE NOTICE 'modb: no current transition graph of profile "%" over %: choosing among all its snippets',
                profile, coalesce('collection ' || collection, 'every collection')
                USING HINT = format('a role that can write builds one with modb.build_transition_graph(name, %L, %L) or `modb graph build`; SET modb.graph = ''none'' for the plain rule without this notice',
                                    profile, collection);
        ELSE
            PERFORM set_config('modb.graph', graph, true);
        END IF;
    END IF;
    IF annotations IS NOT NULL THEN  -- as SET LOCAL modb.annotations would, for this chain only
        PERFORM set_config('modb.annotations', annotations, true);
    END IF;
    RETURN QUERY SELECT * FROM modb.synthesis_chain(targets, max_snippets, start_snippet, start_position, start_heading,
                                                     profile, collection, arrival_radius, exclude_seconds,
                                                     modb.can_rest(collection));
    IF graph IS NOT NULL THEN
        PERFORM set_config('modb.graph', coalesce(knob, ''), true);
    END IF;
    IF annotations IS NOT NULL THEN
        PERFORM set_config('modb.annotations', coalesce(annotations_knob, ''), true);
    END IF;
END
$$;
COMMENT ON FUNCTION modb.synthesize(float8[], int, bigint, float8[], float8, text, text, float8, float8, text) IS
    'A chain of up to max_snippets snippets from start_position/start_heading (world metres, radians; 0 faces +Z) through the world goals in targets ({{x, z}, ...} or {{x, y, z}, ...}), in order: one row per snippet with where it is placed, where it ends, the goal it served and whether it reached it (pelvis within arrival_radius on the ground), and its selection (relaxation level, continuity, proximity). Without collection or start_snippet it draws from the largest skeleton-and-rate pool (modb.snippet_pools); without a graph set (modb.graph) it chooses among the newest current transition graph over that data (modb.default_graph), or says with a NOTICE that there is none; SET modb.graph = ''none'' for the paper''s plain rule. annotations (''walk, !run'') keeps the chain to snippets so annotated, as modb.annotations does. Its first frame stands in for the previous snippet''s last; start_time is the time of that frame. The chain ends early when nothing can follow (every candidate excluded)';
