-- Why a graph of models is broken (96_model_graphs.sql's trigger asks it of every graph written): set-based,
-- so a check takes time in proportion to the graph (0.26.0; it was quadratic), and a graph's size capped.
-- A node's type: start, end, idle, standard, or action (0.29.0: an action reached from idle and back).

CREATE OR REPLACE FUNCTION modb.model_graph_problem(data jsonb, skeleton_id bigint)
RETURNS text
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    max_nodes constant int := 1000;
    max_transitions constant int := 20000;
    n_nodes int;
    n_transitions int;
    problem text;
BEGIN
    IF jsonb_typeof(data) <> 'object' OR jsonb_typeof(data->'nodes') IS DISTINCT FROM 'object'
       OR data->'nodes' = '{}' THEN
        RETURN '"nodes" must be an object naming at least one node: {"name": {"model_id": id, "type": ...}}';
    END IF;
    IF skeleton_id IS NULL THEN
        RETURN 'a graph of models names its skeleton (skeleton_id): every model must be of it';
    END IF;
    IF data ? 'transitions' AND jsonb_typeof(data->'transitions') <> 'array' THEN
        RETURN '"transitions" must be a list of {"from": node, "to": node}';
    END IF;
    n_nodes := (SELECT count(*) FROM jsonb_object_keys(data->'nodes'));
    n_transitions := coalesce(jsonb_array_length(data->'transitions'), 0);
    IF n_nodes > max_nodes OR n_transitions > max_transitions THEN
        RETURN format('a graph of models has at most %s nodes and %s transitions (this one has %s and %s)',
                      max_nodes, max_transitions, n_nodes, n_transitions);
    END IF;
    SELECT CASE
             WHEN jsonb_typeof(n.spec) <> 'object' OR jsonb_typeof(n.spec->'model_id') IS DISTINCT FROM 'number'
                 THEN format('node "%s" must be {"model_id": a modb.models id, "type": ...}', n.name)
             WHEN coalesce(n.spec->>'type', 'standard') NOT IN ('start', 'end', 'idle', 'standard', 'action')
                 THEN format('node "%s": type "%s" is none of start, end, idle, standard, action', n.name,
                             n.spec->>'type')
             WHEN m.id IS NULL OR m.kind <> 'motion_primitive'
                 THEN format('node "%s": there is no motion model with id %s (modb model list names them)',
                             n.name, n.spec->>'model_id')
             WHEN m.skeleton_id IS DISTINCT FROM model_graph_problem.skeleton_id
                 THEN format('node "%s": model %s ("%s") is of skeleton %s, the graph of skeleton %s', n.name,
                             m.id, m.name, m.skeleton_id, model_graph_problem.skeleton_id)
           END INTO problem
      FROM jsonb_each(data->'nodes') AS n(name, spec)
      LEFT JOIN modb.models m
        ON m.id = CASE WHEN jsonb_typeof(n.spec->'model_id') = 'number' THEN (n.spec->>'model_id')::numeric END
     WHERE jsonb_typeof(n.spec) <> 'object' OR jsonb_typeof(n.spec->'model_id') IS DISTINCT FROM 'number'
        OR coalesce(n.spec->>'type', 'standard') NOT IN ('start', 'end', 'idle', 'standard', 'action')
        OR m.id IS NULL OR m.kind <> 'motion_primitive' OR m.skeleton_id IS DISTINCT FROM model_graph_problem.skeleton_id
     ORDER BY n.name LIMIT 1;
    IF problem IS NOT NULL THEN
        RETURN problem;
    END IF;
    -- `?` finds a key of a jsonb object by binary search: each transition costs log(nodes)
    SELECT format('transition %s (%s) must be {"from": node, "to": node} between nodes of the graph', t.k, t.spec)
      INTO problem
      FROM jsonb_array_elements(coalesce(data->'transitions', '[]')) WITH ORDINALITY AS t(spec, k)
     WHERE jsonb_typeof(t.spec) <> 'object' OR jsonb_typeof(t.spec->'from') IS DISTINCT FROM 'string'
        OR jsonb_typeof(t.spec->'to') IS DISTINCT FROM 'string'
        OR NOT (data->'nodes') ? (t.spec->>'from') OR NOT (data->'nodes') ? (t.spec->>'to')
     ORDER BY t.k LIMIT 1;
    IF problem IS NOT NULL THEN
        RETURN problem;
    END IF;
    SELECT format('node "%s" is reached by no transition: add one to it, or mark it a start node', u.name)
      INTO problem
      FROM (SELECT n.key FROM jsonb_each(data->'nodes') n WHERE coalesce(n.value->>'type', 'standard') <> 'start'
            EXCEPT
            SELECT t->>'to' FROM jsonb_array_elements(coalesce(data->'transitions', '[]')) t) AS u(name)
     ORDER BY u.name LIMIT 1;
    RETURN problem;
END
$$;
COMMENT ON FUNCTION modb.model_graph_problem(jsonb, bigint) IS
    'Why a graph of models (modb.graphs kind ''models'') is broken: a malformed document, more than 1,000 nodes or 20,000 transitions, a node naming no motion model or one of another skeleton, a transition between unknown nodes, a node other than a start node that no transition reaches; NULL when it is sound. Its time grows with the graph''s size, not its square';
