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

CREATE OR REPLACE FUNCTION modb._synthesize_from_models(graph text, goals float8[], seconds float8, seed int,
                                             arrival_radius float8)
RETURNS TABLE (fps float8, n_frames int, rotations real[], translations real[], report jsonb)
LANGUAGE plpython3u STABLE PARALLEL UNSAFE  -- plpy.execute opens a subtransaction: not in a parallel worker
AS $py$
#@modb_kernel database model_synthesis
D = kernel.database
try:
    return kernel.model_synthesis.synthesize_stored(D.Server(plpy), graph, goals, seconds, seed, arrival_radius)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
$py$;
COMMENT ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8) IS
    'Internal: what modb.synthesize_from_models runs (PL/Python); call that one, whose errors read without Python''s exception names';
CREATE FUNCTION modb.synthesize_from_models(graph text, goals float8[], seconds float8, seed int DEFAULT 0,
                                            arrival_radius float8 DEFAULT 0.5)
RETURNS TABLE (fps float8, n_frames int, rotations real[], translations real[], report jsonb)
LANGUAGE plpgsql STABLE PARALLEL UNSAFE  -- the EXCEPTION block is a subtransaction: not in a parallel worker
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._synthesize_from_models(graph, goals, seconds, seed, arrival_radius);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8) IS
    'A strip of `seconds` (at most 600) walked by the graph of models named graph (modb.graphs kind ''models'') through goals (float8[][2], world X and Z in metres, followed in order; the character starts with its pelvis above the origin facing +Z): step after step, the next model from the graph''s transitions, turned by a planner that widens before a goal inside its turning circle, its scores found in its k-means tree and refined toward the step''s constraints, placed on the stance foot and joined by inertialization; after the last goal its stop where it has one, then the character comes to rest and stands, idling (its idle model or captured standing frames). One row: the frames as clips keep them (rotations real[n_frames][n_joints][4], translations real[n_frames][n_translated][3]) and a report (per step its node, constraint targets and errors against the best of 300 random samples; goals reached; the frame it came to rest; notes). The same arguments give the same strip';
REVOKE EXECUTE ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8) FROM PUBLIC;
REVOKE EXECUTE ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8) TO modb_reader;
GRANT EXECUTE ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8) TO modb_reader;
