-- How much work a selection did: the candidates select_next_snippet scored for continuity on its way to
-- the relaxation level that answered. Latency follows this count (README "Performance"), and the
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
