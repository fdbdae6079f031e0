-- Graphs of motion models (0.23.0; after the DFKI pipeline): a modb.graphs row of kind 'models' whose data
-- names motion models (modb.models ids) as nodes and the transitions allowed between them:
--   {"nodes": {"left_step": {"model_id": 8, "type": "standard", "action": "walk"}, ...},
--    "transitions": [{"from": "left_step", "to": "right_step"}, ...]}
-- A node's type is start (a walk may begin there), end (played once after the last goal), idle (played
-- over and over after that) or standard. The database checks each graph it is given, so every writer
-- (SQL, REST, the command line, the web view's editor) meets the same check, in words.

CREATE FUNCTION modb.model_graphs_check()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    problem text := modb.model_graph_problem(NEW.data, NEW.skeleton_id);
BEGIN
    IF problem IS NOT NULL THEN
        RAISE EXCEPTION 'graph of models "%" is broken: %', NEW.name, problem
            USING ERRCODE = 'check_violation',
                  HINT = '`modb model graph NAME --collection C` builds a sound one for the step models of a collection';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.model_graphs_check() IS
    'Trigger of modb.graphs: refuses a graph of models that modb.model_graph_problem finds broken, with the reason';
CREATE TRIGGER model_graphs_check BEFORE INSERT OR UPDATE ON modb.graphs
    FOR EACH ROW WHEN (NEW.kind = 'models') EXECUTE FUNCTION modb.model_graphs_check();

