-- Synthesis from a graph of models (0.23.0), with actions (0.29.0, issue 63): the character walks to each
-- action's place, performs it meeting its target and stands again.
CREATE OR REPLACE FUNCTION modb._synthesize_from_models(graph text, goals float8[], seconds float8, seed int,
                                             arrival_radius float8, actions jsonb)
RETURNS TABLE (fps float8, n_frames int, rotations real[], translations real[], report jsonb)
LANGUAGE plpython3u STABLE PARALLEL UNSAFE  -- plpy.execute opens a subtransaction: not in a parallel worker
AS $py$
#@modb_kernel database model_synthesis
D = kernel.database
try:
    return kernel.model_synthesis.synthesize_stored(D.Server(plpy), graph, goals, seconds, seed, arrival_radius,
                                                    actions)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
$py$;
COMMENT ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8, jsonb) IS
    'Internal: what modb.synthesize_from_models runs (PL/Python); call that one, whose errors read without Python''s exception names';
CREATE FUNCTION modb.synthesize_from_models(graph text, goals float8[], seconds float8, seed int DEFAULT 0,
                                            arrival_radius float8 DEFAULT 0.5, actions jsonb DEFAULT NULL)
RETURNS TABLE (fps float8, n_frames int, rotations real[], translations real[], report jsonb)
LANGUAGE plpgsql STABLE PARALLEL UNSAFE  -- the EXCEPTION block is a subtransaction: not in a parallel worker
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._synthesize_from_models(graph, goals, seconds, seed, arrival_radius, actions);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8, jsonb) IS
    'A strip of `seconds` (at most 600) walked by the graph of models named graph (modb.graphs kind ''models'') through goals (float8[][2], world X and Z in metres, followed in order; the character starts with its pelvis above the origin facing +Z): step after step, the next model from the graph''s transitions, turned by a planner that widens before a goal inside its turning circle, its scores found in its k-means tree and refined toward the step''s constraints, placed on the stance foot and joined by inertialization; after the last goal its stop where it has one, then the character comes to rest and stands, idling (its idle model or captured standing frames). actions (jsonb, 0.29.0): a list of {"primitive": an action node of the graph, "target": [x, y, z] where the acting hand is at the action''s keyframe, "stand": [x, z] where to stand (default: within reach of the target), "after": how many goals come before it (default: all), "seconds": how long a repeated motion such as a wave goes on (it faces the target from where the character stands)}: the character walks there, comes to rest, performs it meeting the target (tree search, refinement, then inverse kinematics of the arm) and stands again; goals may then be empty. One row: the frames as clips keep them (rotations real[n_frames][n_joints][4], translations real[n_frames][n_translated][3]) and a report (per step its node, constraint targets and errors against the best of 300 random samples; per action the hand''s error after the tree, the refinement and inverse kinematics; goals reached; the frame it came to rest; notes). The same arguments give the same strip';
REVOKE EXECUTE ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8, jsonb) FROM PUBLIC;
REVOKE EXECUTE ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8, jsonb) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8, jsonb) TO modb_reader;
GRANT EXECUTE ON FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8, jsonb) TO modb_reader;
