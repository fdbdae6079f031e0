-- The checks of a select_next_snippet request, with errors that say what is wrong. CREATE OR REPLACE:
-- upgrades include this file.

CREATE OR REPLACE FUNCTION modb.check_request(prev_snippet bigint, target float8[], k int, collection text)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    -- {x, z} or {x, y, z}: one dimension, subscripts from 1, finite coordinates within 1e9 m (so that no
    -- distance the objective computes overflows). NaN is above every number, so NOT (abs(v) <= 1e9) holds
    -- for it too.
    IF target IS NULL OR array_ndims(target) IS DISTINCT FROM 1 OR cardinality(target) NOT IN (2, 3)
       OR array_lower(target, 1) <> 1
       OR EXISTS (SELECT FROM unnest(target) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target must be {x, z} or {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(target::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value',
                  HINT = 'target is the goal in the avatar''s heading frame at the end of prev_snippet: x left, (y up,) z forward';
    END IF;
    IF k IS NULL OR k < 1 THEN
        RAISE EXCEPTION 'k must be at least 1, got %', coalesce(k::text, 'NULL') USING ERRCODE = 'invalid_parameter_value',
            HINT = 'k is how many of the best continuations select_next_snippets returns';
    END IF;
    IF prev_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = prev_snippet) THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'prev_snippet is a modb.snippets id, or NULL to start';
    END IF;
    IF collection IS NOT NULL AND modb.find_collection(collection) IS NULL THEN
        RAISE EXCEPTION 'no collection "%"', collection USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_request(bigint, float8[], int, text) IS
    'Raises a clear error for a select_next_snippet request that cannot be answered (bad target or k, unknown snippet or collection)';

CREATE OR REPLACE FUNCTION modb.check_world_request("position" float8[], heading float8, target_world float8[])
RETURNS float8[]
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
DECLARE
    target float8[];
BEGIN
    IF "position" IS NULL OR array_ndims("position") IS DISTINCT FROM 1 OR cardinality("position") <> 3
       OR array_lower("position", 1) <> 1
       OR EXISTS (SELECT FROM unnest("position") v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'position must be {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce("position"::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF heading IS NULL OR NOT abs(heading) < 'Infinity' THEN
        RAISE EXCEPTION 'heading must be a finite angle in radians (0 faces +Z), got %', coalesce(heading::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF target_world IS NULL OR array_ndims(target_world) IS DISTINCT FROM 1 OR cardinality(target_world) NOT IN (2, 3)
       OR array_lower(target_world, 1) <> 1
       OR EXISTS (SELECT FROM unnest(target_world) v WHERE v IS NULL OR NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target_world must be {x, z} or {x, y, z} in metres (finite, each coordinate within +-1e9), got %',
            coalesce(target_world::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    target := modb.world_to_local("position", heading, target_world);
    IF EXISTS (SELECT FROM unnest(target) v WHERE NOT abs(v) <= 1e9) THEN
        RAISE EXCEPTION 'target_world % is farther than 1e9 m from position %', target_world, "position"
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN target;
END
$$;
COMMENT ON FUNCTION modb.check_world_request(float8[], float8, float8[]) IS
    'Raises a clear error for select_next_snippet_world arguments that cannot be answered (position, heading, target_world); else the goal in the avatar''s heading frame (modb.world_to_local)';

-- select_next_snippets_reference: continuity (WHERE) and objective (ORDER BY) as one query the planner
-- sees whole; the statement of the rule that select_next_snippets (C, below) follows.
-- The objective (modb.approach_cost): the nearer of where the candidate ends and where it leads
-- (future_translation: itself and up to two play-on snippets) measured against the aim point (the goal,
-- or the point lookahead_distance along the way to a farther one, so that a far goal does not favour the
-- fastest gait, which cannot turn), plus the profile's
-- continuity_weight x its continuity ratio, so a smoother candidate wins unless another serves the goal
-- clearly better. With a transition graph's stored transitions, level 0 ranks by the graph's cost-to-go
-- instead: the time to the goal through the candidate, however many snippets the turn takes (graphs
-- built before 0.6.0 have none: there graph_lookahead scores each candidate also by the best of its
-- successors placed after it). CREATE OR REPLACE: upgrades include this file.
-- LANGUAGE sql, STABLE, not STRICT, one SELECT: inlined into the caller's plan, so EXPLAIN shows the
-- GiST index scan on snippets.begin_features with the profile's box as its Index Cond.

CREATE OR REPLACE FUNCTION modb.frame_key(clip_id bigint, version int, mirrored boolean)
RETURNS numeric
LANGUAGE sql IMMUTABLE PARALLEL SAFE
-- Frames are 0 .. 2^31 - 1 and versions any int: each (clip, version, mirrored) gets a stretch of its own.
RETURN ((clip_id::numeric * 4294967296 + (version::numeric + 2147483648)) * 2 + mirrored::int) * 2147483648;
COMMENT ON FUNCTION modb.frame_key(bigint, int, boolean) IS
    'Internal: where the frames of a clip source (clip, version, as captured or mirrored) start on one line of numbers, a stretch of 2^31 each (frame_key + frame); select_next_snippet keeps the frames it must not replay as one multirange on it';

CREATE OR REPLACE FUNCTION modb.select_next_snippets_reference(prev_snippet bigint, target float8[], k int,
                                          profile text DEFAULT 'default', collection text DEFAULT NULL,
                                          exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
WITH cfg AS MATERIALIZED (
    SELECT plan, checked, collections, modb.aim_point(target, (plan).lookahead_distance) AS aim,
           -- prev's level-0 successors are stored (modb.graph_transitions) for these continuity settings
           EXISTS (SELECT FROM modb.graphs g JOIN modb.graph_transitions e ON e.graph_id = g.id
                    WHERE g.id = (plan).graph_id AND e.from_snippet = prev_snippet
                      AND g.data->'transition_key' = modb.transition_key(plan)) AS stored,
           -- the grid of the graph's cost-to-go, when it has one and the plan ranks by it
           (SELECT g.data->'cost_to_go' FROM modb.graphs g WHERE g.id = (plan).graph_id AND (plan).graph_cost_to_go) AS cost_grid
      FROM (SELECT modb.match_plan(profile) AS plan, modb.check_request(prev_snippet, target, k, collection) AS checked,
                   CASE WHEN collection IS NULL THEN NULL ELSE modb.collection_subtree(collection) END AS collections
            OFFSET 0) resolved  -- not flattened: match_plan runs once, not once per (plan).field above
), prev AS MATERIALIZED (
    SELECT t AS term, t.features, s.pose_key, s.fps
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator
     WHERE s.id = prev_snippet
       AND (SELECT checked FROM cfg)  -- every path reads prev or cfg first: bad requests always raise
), played AS MATERIALIZED (
    -- prev_snippet and the snippets in exclude, each distinct one looked up once.
    SELECT x.clip_id, x.version, x.mirrored, x.first_frame, x.n_frames
      FROM modb.snippets x
     WHERE x.id IN (SELECT e.id FROM unnest(exclude) AS e(id) UNION SELECT prev_snippet)
), played_frames AS MATERIALIZED (
    -- The frames they played after their first (the seam): one multirange on the line of modb.frame_key.
    SELECT coalesce(range_agg(numrange(modb.frame_key(clip_id, version, mirrored) + first_frame + 1,
                                       modb.frame_key(clip_id, version, mirrored) + first_frame + n_frames - 1, '[]')),
                    '{}') AS frames
      FROM played
), candidates AS NOT MATERIALIZED (
    -- The filters every level shares: same skeleton poses and rate, the collection, the transition graph
    -- (when the plan names one: its snippets never lead into a dead end), and no replay of a
    -- frame the previous snippet or a recent one covered (its first frame, the seam, aside).
    SELECT s.*
      FROM modb.snippets s
     WHERE (collection IS NULL OR s.collection_id = ANY ((SELECT collections FROM cfg)::bigint[]))
       AND ((SELECT (plan).graph_id FROM cfg) IS NULL
            OR EXISTS (SELECT FROM modb.graph_snippets g
                        WHERE g.graph_id = (SELECT (plan).graph_id FROM cfg) AND g.snippet_id = s.id))
       -- the annotation names the plan keeps to (modb.annotated), when it names any
       AND ((SELECT (plan).annotations FROM cfg) IS NULL
            OR modb.annotated(s.clip_id, s.version, s.first_frame, s.n_frames, (SELECT (plan).annotations FROM cfg)))
       -- A candidate from a clip source nothing played is in (a hashed look-up); one from a played source
       -- when its frames miss the played ones (a binary search): time linear in the length of exclude,
       -- where testing every id against every candidate (before 0.9.0) was quadratic. An anti-join with
       -- the one row of played_frames, so that the box scans still hand on every candidate they found.
       AND NOT EXISTS (SELECT FROM played_frames f
                        WHERE (s.clip_id, s.version, s.mirrored) IN (SELECT p.clip_id, p.version, p.mirrored FROM played p)
                          AND f.frames && numrange(modb.frame_key(s.clip_id, s.version, s.mirrored) + s.first_frame + 1,
                                                   modb.frame_key(s.clip_id, s.version, s.mirrored) + s.first_frame + s.n_frames - 1, '[]'))
)
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)) AS proximity,
        0, NULL::float8, c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c
  WHERE prev_snippet IS NULL AND (SELECT checked FROM cfg)
  ORDER BY 7, 1 LIMIT k)
-- Relaxation levels 0-3: every threshold (and the box) scaled by 2^level; a row reports the lowest
-- level it satisfies. Level 4, the last: the nearest start configuration (feature distance), any ratio.
-- Level 0 from a graph's stored transitions when it has them for prev and these settings, else the box.
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames, o.objective, 0, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM modb.graph_transitions e CROSS JOIN LATERAL unnest(e.to_snippets) AS next(id)
   JOIN candidates c ON c.id = next.id
   JOIN modb.graph_transitions ce ON ce.graph_id = e.graph_id AND ce.from_snippet = c.id  -- the candidate's own row
   JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  -- graph_lookahead (graphs without a cost-to-go): the best of this candidate's successors in the graph,
  -- placed after it, may stand in for where it leads (a turn that only the next snippet completes);
  -- least() ignores the NULL without it.
  CROSS JOIN LATERAL (
      SELECT min(modb.approach_cost(n2.net_translation, n2.future_translation, n2.future_heading,
                                    modb.aim_point(modb.world_to_local(c.net_translation, c.net_heading, target), (cfg.plan).lookahead_distance),
                                    (cfg.plan).heading_weight)) AS cost
        FROM unnest(ce.to_snippets) AS next2(id) JOIN modb.snippets n2 ON n2.id = next2.id
       WHERE (cfg.plan).graph_lookahead AND cfg.cost_grid IS NULL) two
  -- The objective in metres: with the graph's cost-to-go, the seconds to the goal through this candidate
  -- (its own duration, then the cost-to-go from its end) at the graph's median speed; else as the box levels.
  CROSS JOIN LATERAL (
      SELECT CASE WHEN cfg.cost_grid IS NOT NULL
                  THEN (cfg.cost_grid->>'speed')::float8
                       * ((c.n_frames - 1) / c.fps
                          + modb.cost_to_go(ce.cost_to_go, modb.world_to_local(c.net_translation, c.net_heading, target), cfg.cost_grid))
                  ELSE least(modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, cfg.aim, (cfg.plan).heading_weight),
                             two.cost) END AS objective) o
  WHERE (SELECT stored FROM cfg)
    AND e.graph_id = (SELECT (plan).graph_id FROM cfg) AND e.from_snippet = prev_snippet
    AND r.ratio <= 1.0
  ORDER BY o.objective + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 0, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE NOT (SELECT stored FROM cfg)
    AND c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 1.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 1.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 1, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 2.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 2.0 AND r.ratio > 1.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 2, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 4.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 4.0 AND r.ratio > 2.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 3, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 8.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 8.0 AND r.ratio > 4.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)),
        4, modb.continuity_ratio(prev.term, b, cfg.plan),
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg
  WHERE prev_snippet IS NOT NULL
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND modb.continuity_ratio(prev.term, b, cfg.plan) > 8
  ORDER BY c.begin_features <-> (SELECT features FROM prev), c.id LIMIT k)
-- k through cfg: the request is checked before a LIMIT of 0 or less could end the query or fail on it.
LIMIT (SELECT k FROM cfg WHERE checked)
$$;
COMMENT ON FUNCTION modb.select_next_snippets_reference(bigint, float8[], int, text, text, bigint[]) IS
    'The rule of select_next_snippets as one SQL query (the planner sees it whole: EXPLAIN shows its GiST box scans); select_next_snippets returns the same rows, faster. The k best continuations of prev_snippet toward target ({x, z} or {x, y, z}, metres, in the avatar''s heading frame at its end), ordered by relaxation level, then proximity (from the nearer of where the snippet ends and where it leads to the aim point: the target, or the point the profile''s lookahead_distance along the way to it) + continuity_weight x continuity (from a graph snippet at level 0: with the graph''s cost-to-go, the seconds to the goal through the candidate x the graph''s median speed; else with graph_lookahead, the proximity of the candidate or of its best successor, whichever is nearer); prev_snippet NULL: the snippets that best serve the target';

-- The same rule in C (src/selection.c), without planning a query per call: the plan resolved once per
-- session, the box read by kept generic plans, candidates scored in C; a start and level 4 are answered by
-- the reference above. Not STRICT: prev_snippet NULL is a start.
CREATE OR REPLACE FUNCTION modb.select_next_snippets(prev_snippet bigint, target float8[], k int,
                                          profile text DEFAULT 'default', collection text DEFAULT NULL,
                                          exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE c STABLE CALLED ON NULL INPUT PARALLEL SAFE COST 1000 ROWS 5
AS 'MODULE_PATHNAME', 'modb_select_next_snippets';
COMMENT ON FUNCTION modb.select_next_snippets(bigint, float8[], int, text, text, bigint[]) IS
    'The k best continuations of prev_snippet toward target ({x, z} or {x, y, z}, metres, in the avatar''s heading frame at its end), ordered by relaxation level, then proximity (from the nearer of where the snippet ends and where it leads to the aim point: the target, or the point the profile''s lookahead_distance along the way to it) + continuity_weight x continuity (from a graph snippet at level 0: with the graph''s cost-to-go, the seconds to the goal through the candidate x the graph''s median speed; else with graph_lookahead, the proximity of the candidate or of its best successor, whichever is nearer); prev_snippet NULL: the snippets that best serve the target';

CREATE OR REPLACE FUNCTION modb.explain_selection(prev_snippet bigint, target float8[], k int DEFAULT 1,
                                          profile text DEFAULT 'default', collection text DEFAULT NULL,
                                          exclude bigint[] DEFAULT NULL, verbose boolean DEFAULT false)
RETURNS SETOF text
LANGUAGE c STABLE CALLED ON NULL INPUT PARALLEL SAFE COST 1000 ROWS 24
AS 'MODULE_PATHNAME', 'modb_explain_selection';
COMMENT ON FUNCTION modb.explain_selection(bigint, float8[], int, text, text, bigint[], boolean) IS
    'How select_next_snippets answers this call (its arguments, in its order), in at most 40 lines of at most 120 characters: which path answered, and per relaxation level the blocks its box met, the blocks and candidates the term codes rejected (by term kind), the rows read, in the box, filtered, within the continuity ratio and returned, and the time of each stage; verbose adds the profile as resolved and each level''s box';

CREATE OR REPLACE FUNCTION modb.select_next_snippet(prev_snippet bigint, target float8[], profile text DEFAULT 'default',
                                         collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT * FROM modb.select_next_snippets(prev_snippet, target, 1, profile, collection, exclude)
$$;
COMMENT ON FUNCTION modb.select_next_snippet(bigint, float8[], text, text, bigint[]) IS
    'The snippet that continues prev_snippet smoothly (the profile''s thresholds, relaxed in steps when nothing passes) and brings the avatar nearest to target ({x, z} or {x, y, z} metres in its heading frame at the end of prev_snippet; x left, z forward). prev_snippet NULL: the snippet that best serves the target. exclude: recently played snippets, whose frames are not replayed';

CREATE OR REPLACE FUNCTION modb.world_to_local(origin float8[], heading float8, target_world float8[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- Heading theta faces (sin theta, 0, cos theta); the character's left is (cos theta, 0, -sin theta).
RETURN CASE WHEN array_length(target_world, 1) = 3
    THEN ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[3] - origin[3]) * sin(heading),
               target_world[2] - origin[2],
               (target_world[1] - origin[1]) * sin(heading) + (target_world[3] - origin[3]) * cos(heading)]
    ELSE ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[2] - origin[3]) * sin(heading),
               (target_world[1] - origin[1]) * sin(heading) + (target_world[2] - origin[3]) * cos(heading)] END;
COMMENT ON FUNCTION modb.world_to_local(float8[], float8, float8[]) IS
    'A world target ({x, z} on the ground or {x, y, z}) in the heading frame of a character at origin {x, y, z} with heading theta';

CREATE OR REPLACE FUNCTION modb.select_next_snippet_world(prev_snippet bigint, "position" float8[], heading float8,
                                               target_world float8[], profile text DEFAULT 'default',
                                               collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
-- The world arguments checked and the goal converted once, first (OFFSET 0: not flattened into every
-- place select_next_snippets reads its target); select_next_snippets is still inlined, beside it.
SELECT n.*
  FROM (SELECT modb.check_world_request(select_next_snippet_world."position", heading, target_world) AS target
        OFFSET 0) w
 CROSS JOIN LATERAL modb.select_next_snippets(prev_snippet, w.target, 1, profile, collection, exclude) n
$$;
COMMENT ON FUNCTION modb.select_next_snippet_world(bigint, float8[], float8, float8[], text, text, bigint[]) IS
    'select_next_snippet with the goal in world coordinates: the avatar at position {x, y, z} with heading theta (radians, 0 = facing +Z)';

-- How much work a selection did: the candidates select_next_snippet scored for continuity on its way to
-- the relaxation level that answered. Latency follows this count (docs/performance.md), and the
-- thresholds, joints and velocity terms move it; the avatar view reports it after every selection.
-- CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.candidates_examined(prev_snippet bigint, relax_level int, profile text DEFAULT 'default')
RETURNS bigint
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    plan modb.match_plan := modb.match_plan(profile);
    prev record;
    stored int;
    level int;
    total bigint := 0;
    n bigint;
BEGIN
    IF relax_level IS NULL OR relax_level NOT BETWEEN 0 AND 4 THEN
        RAISE EXCEPTION 'relax_level must be 0-4 (select_next_snippet''s relax_level), got %', relax_level;
    END IF;
    IF prev_snippet IS NULL THEN  -- a start ranks every snippet
        RETURN (SELECT count(*) FROM modb.snippets);
    END IF;
    SELECT t.features, s.pose_key, s.fps INTO prev
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = prev_snippet;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING HINT = 'prev_snippet is a modb.snippets id';
    END IF;
    -- Level 0 from the graph's stored transitions, under the same condition as select_next_snippet.
    SELECT cardinality(e.to_snippets) INTO stored
      FROM modb.graphs g JOIN modb.graph_transitions e ON e.graph_id = g.id
     WHERE g.id = plan.graph_id AND e.from_snippet = prev_snippet
       AND g.data->'transition_key' = modb.transition_key(plan);
    FOR level IN 0 .. relax_level LOOP
        IF level = 0 AND stored IS NOT NULL THEN
            n := stored;
        ELSIF level = 4 THEN  -- the nearest start configuration among every snippet of the same pose and rate
            SELECT count(*) INTO n FROM modb.snippets c WHERE c.pose_key = prev.pose_key AND c.fps = prev.fps;
        ELSE  -- what the GiST box of this level yields
            SELECT count(*) INTO n FROM modb.snippets c
             WHERE c.begin_features <@ modb.match_box(prev.features, plan, 2.0 ^ level)
               AND c.pose_key = prev.pose_key AND c.fps = prev.fps;
        END IF;
        total := total + n;
    END LOOP;
    RETURN total;
END
$$;
COMMENT ON FUNCTION modb.candidates_examined(bigint, int, text) IS
    'The candidates select_next_snippet scored for continuity after prev_snippet, summed over the relaxation levels it tried up to relax_level (the one it answered at): at each level the snippets of the same pose and rate in its search box (level 0 of a transition graph that stores prev''s successors: those; level 4: all), before the collection, graph and exclude filters. Reads this session''s SET modb.<knob> like the selection; prev_snippet NULL: every snippet';
