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
-- standing (or walking), the smoothest level first, then the one ending nearest the goal.
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
       CASE WHEN r.ratio <= 1 THEN 0 ELSE ceil(log(2.0, r.ratio::numeric))::int END, r.ratio,
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

CREATE OR REPLACE FUNCTION modb.select_snippet_ending(prev_snippet bigint, "position" float8[], heading float8,
                                                     target_world float8[], profile text, collection text,
                                                     exclude bigint[], standing boolean)
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
COMMENT ON FUNCTION modb.select_snippet_ending(bigint, float8[], float8, float8[], text, text, bigint[], boolean) IS
    'The snippet that continues prev most smoothly (relaxation level 0-3) among those of its pool that end standing (pelvis slower than modb.rest_speed()) or, standing false, walking (at least modb.walk_speed()), then the one ending nearest the goal; the columns of select_next_snippet_world; no row when the data has none';

CREATE OR REPLACE FUNCTION modb.can_rest(collection text DEFAULT NULL)
RETURNS boolean
LANGUAGE sql STABLE PARALLEL SAFE
RETURN EXISTS (SELECT FROM modb.snippets s
                WHERE (collection IS NULL OR s.collection_id = ANY (modb.collection_subtree(collection)))
                  AND modb.end_speed(s.id) < modb.rest_speed());
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
