-- Coming to rest and setting off again: once the last goal is reached, synthesis (modb.synthesize, the
-- Python Avatar) stops walking and stands, with stopping and standing motion from the data, instead of
-- circling the goal; from standing, a new goal starts it walking with motion that sets off. Such motion
-- is outside any transition graph (a graph keeps the turning part of the data), and the rule that
-- chooses the smoothest seam first would keep a standing avatar standing, so both are chosen here among
-- every snippet of the pool that ends as wanted. CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.rest_speed()
RETURNS float8
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN 0.1;
COMMENT ON FUNCTION modb.rest_speed() IS
    'm/s: a snippet whose pelvis moves slower than this over the ground at its end ends standing';

CREATE OR REPLACE FUNCTION modb.walk_speed()
RETURNS float8
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN 0.5;
COMMENT ON FUNCTION modb.walk_speed() IS
    'm/s: a snippet whose pelvis moves at least this fast over the ground at its end ends walking';

CREATE OR REPLACE FUNCTION modb.end_speed(snippet bigint)
RETURNS float8
LANGUAGE sql STABLE STRICT PARALLEL SAFE
RETURN (SELECT sqrt(e.velocities[1] ^ 2 + e.velocities[3] ^ 2)
          FROM modb.snippets s JOIN modb.terminators e ON e.id = s.end_terminator
         WHERE s.id = snippet);
COMMENT ON FUNCTION modb.end_speed(bigint) IS 'm/s: how fast a snippet''s pelvis moves over the ground at its end';

CREATE OR REPLACE FUNCTION modb.snippets_ending_within(prev_snippet bigint, "position" float8[], heading float8,
                                                      target_world float8[], profile text, collection text,
                                                      exclude bigint[], standing boolean, scale float8)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
-- The snippets of prev's pool that follow it within ratio `scale` (in that relaxed box) and end
-- standing (or walking), the smoothest level first (the least L with ratio <= 2^L, compared as float8
-- as the scale is, up to L = 3, the reference's widest; 0.28.0 and before took ceil(log(2,
-- ratio::numeric)), of 15 digits, which put a ratio a rounding above 2^L at level L), then the one
-- ending nearest the goal.
WITH prev AS MATERIALIZED (
    SELECT s.pose_key, s.fps, e AS terminator, p AS plan,
           modb.check_world_request(snippets_ending_within."position", heading, target_world) AS target
      FROM modb.snippets s
      JOIN modb.terminators e ON e.id = s.end_terminator
     CROSS JOIN modb.match_plan(profile) p
     WHERE s.id = prev_snippet
)
SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
       sqrt((c.net_translation[1] - prev.target[1]) ^ 2 + (c.net_translation[3] - prev.target[2]) ^ 2),
       CASE WHEN r.ratio <= 1 THEN 0 WHEN r.ratio <= 2 THEN 1 WHEN r.ratio <= 4 THEN 2 WHEN r.ratio <= 8 THEN 3
            ELSE ceil(log(2.0, r.ratio::numeric))::int END, r.ratio,
       c.net_translation, c.net_rotation, c.net_heading
  FROM prev
  JOIN modb.snippets c ON c.begin_features <@ modb.match_box((prev.terminator).features, prev.plan, scale)
                      AND c.pose_key = prev.pose_key AND c.fps = prev.fps
  JOIN modb.terminators b ON b.id = c.begin_terminator
  JOIN modb.terminators e ON e.id = c.end_terminator
 CROSS JOIN LATERAL (SELECT sqrt(e.velocities[1] ^ 2 + e.velocities[3] ^ 2) AS speed) v
 CROSS JOIN LATERAL (SELECT modb.continuity_ratio_native(prev.terminator, b, prev.plan) AS ratio) r
 WHERE (collection IS NULL OR c.collection_id = ANY (modb.collection_subtree(collection)))
   AND c.id <> ALL (coalesce(exclude, '{}'))
   AND CASE WHEN standing THEN v.speed < modb.rest_speed() ELSE v.speed >= modb.walk_speed() END
   AND r.ratio <= scale
   AND ((prev.plan).annotations IS NULL  -- modb.annotations holds for coming to rest and setting off too
        OR modb.annotated(c.clip_id, c.version, c.first_frame, c.n_frames, (prev.plan).annotations))
 ORDER BY 8, 7, 1
$$;
COMMENT ON FUNCTION modb.snippets_ending_within(bigint, float8[], float8, float8[], text, text, bigint[], boolean, float8) IS
    'The snippets of prev''s pool that follow it with a continuity ratio of at most scale, keep to the profile''s or session''s annotations (modb.annotations) and end standing (pelvis slower than modb.rest_speed()) or, standing false, walking (at least modb.walk_speed()), by relaxation level, then nearest the goal at their end';

CREATE OR REPLACE FUNCTION modb.select_snippet_ending_reference(prev_snippet bigint, "position" float8[],
                                                               heading float8, target_world float8[], profile text,
                                                               collection text, exclude bigint[], standing boolean)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    -- Level by level (boxes 1, 2, 4, 8 x the thresholds): the first that has one answers, as a
    -- search of the widest box ordered by level would, without reading it.
    FOR level IN 0..3 LOOP
        RETURN QUERY SELECT * FROM modb.snippets_ending_within(prev_snippet, "position", heading, target_world,
                                                               profile, collection, exclude, standing, 2.0 ^ level)
                      LIMIT 1;
        EXIT WHEN FOUND;
    END LOOP;
END
$$;
COMMENT ON FUNCTION modb.select_snippet_ending_reference(bigint, float8[], float8, float8[], text, text, bigint[], boolean) IS
    'The rule of coming to rest and setting off (0.14.0 to 0.17.0 select_snippet_ending, kept as its statement): the snippet that continues prev most smoothly (relaxation level 0-3) among those of its pool that end standing (pelvis slower than modb.rest_speed()) or, standing false, walking (at least modb.walk_speed()), then the one ending nearest the goal; the columns of select_next_snippet_world; no row when the data has none';

-- The same rule by the box search over snippet blocks and their term codes (src/selection.c, 0.18.0):
-- the reference read every snippet of a box four times as wide at the levels it needed (seconds on a
-- large pool).
CREATE OR REPLACE FUNCTION modb.select_snippet_ending(prev_snippet bigint, "position" float8[], heading float8,
                                                     target_world float8[], profile text, collection text,
                                                     exclude bigint[], standing boolean)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE c STABLE CALLED ON NULL INPUT PARALLEL SAFE COST 1000 ROWS 1
AS 'MODULE_PATHNAME', 'modb_select_snippet_ending';
COMMENT ON FUNCTION modb.select_snippet_ending(bigint, float8[], float8, float8[], text, text, bigint[], boolean) IS
    'The snippet that continues prev most smoothly (relaxation level 0-3) among those of its pool that end standing (pelvis slower than modb.rest_speed()) or, standing false, walking (at least modb.walk_speed()), then the one ending nearest the goal; the columns of select_next_snippet_world; no row when the data has none. The rule is modb.select_snippet_ending_reference; this answers it by the box search over snippet blocks';

CREATE OR REPLACE FUNCTION modb.can_rest(collection text DEFAULT NULL)
RETURNS boolean
LANGUAGE sql STABLE PARALLEL SAFE
-- From the collection's clips (a few) to their snippets by index, the subtree computed once (0.28.0 and
-- before computed it again for every snippet: 3.7 s for collection cmu of all the shipped data).
RETURN EXISTS (SELECT FROM modb.clips c
                 JOIN modb.snippets s ON s.clip_id = c.id AND s.collection_id = c.collection_id
                 JOIN modb.terminators e ON e.id = s.end_terminator
                WHERE (collection IS NULL OR c.collection_id = ANY ((SELECT modb.collection_subtree(collection))::bigint[]))
                  AND sqrt(e.velocities[1] ^ 2 + e.velocities[3] ^ 2) < modb.rest_speed());
COMMENT ON FUNCTION modb.can_rest(text) IS
    'Whether the collection (NULL: every one) has a snippet that ends standing: synthesis comes to rest after its last goal only then';

CREATE OR REPLACE FUNCTION modb.select_synthesis_step(prev_snippet bigint, "position" float8[], heading float8,
                                                     target_world float8[], profile text, collection text,
                                                     exclude bigint[], resting boolean)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
-- Resting (the last goal reached): motion that ends standing. Else, from standing: motion that sets
-- off. Else, or where the data has neither: select_next_snippet_world.
SELECT x.snippet_id, x.clip_id, x.version, x.mirrored, x.first_frame, x.n_frames, x.proximity, x.relax_level,
       x.continuity, x.net_translation, x.net_rotation, x.net_heading
  FROM (SELECT 0 AS rank, r.*
          FROM modb.select_snippet_ending(prev_snippet, "position", heading, target_world, profile, collection,
                                          exclude, true) r
         WHERE resting
        UNION ALL
        SELECT 1, s.*
          FROM modb.select_snippet_ending(prev_snippet, "position", heading, target_world, profile, collection,
                                          exclude, false) s
         WHERE NOT resting AND modb.end_speed(prev_snippet) < modb.rest_speed()
        UNION ALL
        SELECT 2, w.*
          FROM modb.select_next_snippet_world(prev_snippet, "position", heading, target_world, profile, collection,
                                              exclude) w) x
 ORDER BY x.rank
 LIMIT 1
$$;
COMMENT ON FUNCTION modb.select_synthesis_step(bigint, float8[], float8, float8[], text, text, bigint[], boolean) IS
    'A synthesis step after prev (modb.synthesize, the Avatar): resting (the last goal reached), the smoothest snippet that ends standing; from standing, the smoothest that ends walking; else, or where the data has no such snippet, select_next_snippet_world';

-- What synthesis draws from when its caller names neither a collection nor a start (the skeleton-and-rate
-- pool with the most snippets), and the transition graph it uses when the session names none (the newest
-- current one of its profile over that collection): modb.synthesize, `modb synth` and the Python Avatar
-- all ask these, so they give the same chain. CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.graph_is_current(graph_id bigint)
RETURNS boolean
LANGUAGE sql STABLE STRICT PARALLEL SAFE
-- A load replaces snippets (new ids): the graph's rows of removed snippets go with them (ON DELETE
-- CASCADE) and new snippets are not in it, so either count changing means it is stale. So is a graph
-- built before 0.6.0, which stored no transitions (no transition_key) or no cost-to-go.
RETURN (SELECT g.data ?& '{transition_key,cost_to_go}'
               AND (SELECT count(*) FROM modb.graph_snippets gs WHERE gs.graph_id = g.id) = (g.data->>'kept')::bigint
               AND (SELECT count(*) FROM modb.snippets s
                     WHERE g.data->>'collection' IS NULL
                        OR s.collection_id = ANY (modb.collection_subtree(g.data->>'collection')))
                   = (g.data->>'snippets')::bigint
          FROM modb.graphs g
         WHERE g.id = graph_id AND g.kind = 'transitions');
COMMENT ON FUNCTION modb.graph_is_current(bigint) IS
    'Whether a transition graph still covers its scope: no snippet of its collection loaded or removed since it was built (NULL for no such graph)';

CREATE OR REPLACE FUNCTION modb.snippet_pools()
RETURNS TABLE (pose_key text, fps float8, snippets bigint, collection text)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
-- A chain never mixes skeletons or rates (pose_key, fps): each such pool, largest first, with the deepest
-- collection that holds all of its snippets (NULL when only every collection together does).
WITH pools AS (
    SELECT s.pose_key, s.fps, count(*) AS snippets, array_agg(DISTINCT s.collection_id) AS collection_ids
      FROM modb.snippets s
     GROUP BY s.pose_key, s.fps
), paths AS (
    SELECT p.pose_key, p.fps, p.snippets,
           ARRAY(SELECT modb.collection_path(c) FROM unnest(p.collection_ids) c ORDER BY 1) AS paths
      FROM pools p
)
SELECT p.pose_key, p.fps, p.snippets,
       (SELECT nullif(array_to_string(first[1:common], '/'), '')
          FROM (SELECT string_to_array(p.paths[1], '/') AS first) f
         CROSS JOIN LATERAL (  -- the parts every path shares with the first, from the start
             SELECT coalesce(min(k) - 1, cardinality(f.first)) AS common
               FROM unnest(p.paths) other,
                    generate_subscripts(f.first, 1) k
              WHERE f.first[k] IS DISTINCT FROM (string_to_array(other, '/'))[k]) c)
  FROM paths p
 ORDER BY p.snippets DESC, p.pose_key, p.fps
$$;
COMMENT ON FUNCTION modb.snippet_pools() IS
    'Each skeleton-and-rate pool of snippets (pose_key, fps), largest first, with the deepest collection holding all of it (NULL: only all collections do); synthesis without a collection or start draws from the first';

CREATE OR REPLACE FUNCTION modb.default_graph(profile text DEFAULT 'default', collection text DEFAULT NULL)
RETURNS text
LANGUAGE sql STABLE PARALLEL SAFE
-- A graph over a collection containing this one serves it too (its kept snippets within the collection
-- are chosen among); the nearest scope first, then the newest.
RETURN (SELECT g.name
          FROM modb.graphs g
         CROSS JOIN LATERAL (SELECT trim(BOTH '/' FROM g.data->>'collection') AS scope,
                                    trim(BOTH '/' FROM collection) AS wanted) c
         WHERE g.kind = 'transitions' AND g.data->>'profile' = profile
           AND (c.scope IS NULL OR c.wanted = c.scope OR starts_with(c.wanted, c.scope || '/'))
           AND modb.graph_is_current(g.id)
         ORDER BY length(c.scope) DESC NULLS LAST, g.id DESC
         LIMIT 1);
COMMENT ON FUNCTION modb.default_graph(text, text) IS
    'The transition graph synthesis uses when the session names none: the newest current one built with this profile over this collection, else over the nearest collection containing it, else over every collection (NULL: none)';

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
