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
