-- What building a transition graph reads and writes, as functions (0.19.0): modb.build_transition_graph
-- (PL/Python, in the server) and a job worker on any machine (client/modb/jobs) read the same rows, compute
-- with the same kernel (modb_kernel/graph_build.py) and store the result the same way.

CREATE FUNCTION modb.transition_graph_inputs(name text, collection text DEFAULT NULL,
                                             min_turn_degrees float8 DEFAULT 45)
RETURNS TABLE (id bigint, begin_terminator bigint, end_terminator bigint, grp text, future_heading float8,
               clip text, first_frame int, n_frames int, net_x float8, net_z float8, net_heading float8,
               duration float8)
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    ids bigint[];
BEGIN
    IF name IS NULL OR name = '' THEN
        RAISE EXCEPTION 'a transition graph needs a name' USING ERRCODE = '22023';
    END IF;
    IF lower(trim(name)) IN ('none', 'profile') THEN
        RAISE EXCEPTION '"%" cannot name a graph: SET modb.graph = ''%'' means %', name, lower(trim(name)),
            CASE lower(trim(name)) WHEN 'none' THEN 'no graph' ELSE 'the profile''s graph' END
            USING ERRCODE = '22023', HINT = 'choose another name';
    END IF;
    IF min_turn_degrees IS NULL OR NOT min_turn_degrees BETWEEN 0 AND 180 THEN
        RAISE EXCEPTION 'min_turn_degrees must be between 0 and 180, got %', min_turn_degrees USING ERRCODE = '22023';
    END IF;
    IF collection IS NOT NULL THEN
        ids := modb.collection_subtree(collection);
        IF cardinality(ids) IS NULL OR cardinality(ids) = 0 THEN
            RAISE EXCEPTION 'no collection "%"', collection USING ERRCODE = 'P0002',
                HINT = 'modb.collection_path(id) names the stored ones';
        END IF;
    END IF;
    RETURN QUERY
    SELECT s.id, s.begin_terminator, s.end_terminator, s.pose_key || '@' || s.fps, s.future_heading::float8,
           s.clip_id || '/' || s.version || '/' || s.mirrored, s.first_frame, s.n_frames,
           s.net_translation[1]::float8, s.net_translation[3]::float8, s.net_heading::float8,
           ((s.n_frames - 1) / s.fps)::float8
      FROM modb.snippets s WHERE ids IS NULL OR s.collection_id = ANY (ids) ORDER BY s.id;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no snippets to build a graph from%',
            CASE WHEN collection IS NULL THEN '' ELSE format(' in collection "%s"', collection) END
            USING ERRCODE = 'P0002', HINT = '`modb load` builds snippets';
    END IF;
END
$$;
COMMENT ON FUNCTION modb.transition_graph_inputs(text, text, float8) IS
    'The snippets a transition graph of that name over the collection (and those below it; NULL: all) is built from, in id order, with what the build needs of each; errors for a name a graph cannot have, a min_turn_degrees outside 0-180, an unknown collection or no snippets';

CREATE FUNCTION modb.transition_graph_terminators(ids bigint[])
RETURNS TABLE (id bigint, positions real[], rotations real[], velocities real[], angular_velocities real[],
               features float8[])
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT t.id, t.positions, t.rotations, t.velocities, t.angular_velocities,
           (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i) FROM generate_series(1, cube_dim(t.features)) i)
      FROM modb.terminators t WHERE t.id = ANY (ids);
END;
COMMENT ON FUNCTION modb.transition_graph_terminators(bigint[]) IS
    'The terminators (each once) a transition graph build reads: joints'' positions, rotations, velocities and angular velocities, and the feature vector as an array';

CREATE FUNCTION modb.store_transition_graph(name text, data jsonb, kept bigint[], from_snippets bigint[],
                                            to_snippets bigint[], cost_to_go real[], cost_width int)
RETURNS bigint
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    graph_id bigint;
BEGIN
    IF cardinality(from_snippets) IS DISTINCT FROM cardinality(to_snippets)
       OR cardinality(cost_to_go) IS DISTINCT FROM cardinality(kept) * cost_width THEN
        RAISE EXCEPTION 'transition graph "%": % sources for % targets, % costs for % kept snippets of % each',
            name, cardinality(from_snippets), cardinality(to_snippets), cardinality(cost_to_go), cardinality(kept),
            cost_width USING ERRCODE = '22023';
    END IF;
    -- The old graph goes with its name, its rows with it.
    DELETE FROM modb.graph_names g WHERE g.name = store_transition_graph.name AND g.kind = 'transitions';
    INSERT INTO modb.graph_names (name, kind) VALUES (store_transition_graph.name, 'transitions');
    INSERT INTO modb.graphs (name, kind, data) VALUES (store_transition_graph.name, 'transitions', data)
        RETURNING id INTO graph_id;
    INSERT INTO modb.graph_snippets (graph_id, snippet_id) SELECT graph_id, unnest(kept);
    -- One row per kept snippet: its successors, and row k of the costs for the k-th kept snippet.
    INSERT INTO modb.graph_transitions (graph_id, from_snippet, to_snippets, cost_to_go)
    SELECT graph_id, e.f, e.t, cost_to_go[(k.i - 1) * cost_width + 1 : k.i * cost_width]
      FROM (SELECT f, array_agg(t ORDER BY t) AS t FROM unnest(from_snippets, to_snippets) AS e(f, t) GROUP BY f) e
      JOIN unnest(kept) WITH ORDINALITY AS k(id, i) ON k.id = e.f;
    RETURN graph_id;
END
$$;
COMMENT ON FUNCTION modb.store_transition_graph(text, jsonb, bigint[], bigint[], bigint[], real[], int) IS
    'Stores a computed transition graph under its name (replacing one of that name, with its rows): data (modb.graphs.data), the kept snippet ids, its transitions as parallel arrays of from and to ids, and cost_width costs per kept snippet in kept''s order; returns the modb.graphs id';
REVOKE EXECUTE ON FUNCTION modb.store_transition_graph(text, jsonb, bigint[], bigint[], bigint[], real[], int)
    FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.store_transition_graph(text, jsonb, bigint[], bigint[], bigint[], real[], int)
    TO modb_loader;
