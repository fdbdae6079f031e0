-- Action primitives (0.29.0): an action done standing (raise a hand, wave) found from the motion and written
-- as annotation segments, with its standing lead-in and lead-out. The kernel does the work (actions.py and
-- action_annotations.py), here and in job workers.

CREATE OR REPLACE FUNCTION modb._annotate_action(clip bigint, action text)
RETURNS TABLE (version int, name text, start_frame int, end_frame int, keyframes int[], hands text[], kind text)
LANGUAGE plpython3u VOLATILE STRICT PARALLEL UNSAFE
AS $py$
#@modb_kernel database action_annotations
D = kernel.database
try:
    version, made = kernel.action_annotations.annotate(D.Server(plpy), clip, action)
except D.StoreError as e:
    D.raise_in_plpy(plpy, e)
return [(version, s["name"], s["start"], s["end"], s["keyframes"], s.get("hands"), s.get("kind"))
        for s in made]
$py$;
COMMENT ON FUNCTION modb._annotate_action(bigint, text) IS
    'Internal: what modb.annotate_action runs (PL/Python); call that one, whose errors read without Python''s exception names';
REVOKE EXECUTE ON FUNCTION modb._annotate_action(bigint, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb._annotate_action(bigint, text) TO modb_loader;
CREATE FUNCTION modb.annotate_action(clip bigint, action text)
RETURNS TABLE (version int, name text, start_frame int, end_frame int, keyframes int[], hands text[], kind text)
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    message text; error_state text; detail text; hint text;
BEGIN
    RETURN QUERY SELECT * FROM modb._annotate_action(clip, action);
EXCEPTION WHEN OTHERS THEN  -- the error again, in words (15_errors_in_words.sql)
    GET STACKED DIAGNOSTICS message = MESSAGE_TEXT, error_state = RETURNED_SQLSTATE, detail = PG_EXCEPTION_DETAIL,
                            hint = PG_EXCEPTION_HINT;
    PERFORM modb.raise_in_words(message, error_state, detail, hint);
END
$$;
COMMENT ON FUNCTION modb.annotate_action(bigint, text) IS
    'Finds the action done standing in the clip''s current version (FK wrists relative to the pelvis, turned with the hip heading) and writes it as annotation segments marked "auto": the segment named action, with the hands that act ("hands": those whose wrist spans more than a quarter of the arm, both when their paths are within a factor two) and its kind: "repeat" (a wave: at least 4 like swings back and forth; keyframes its ends and the first and last turning point) or "reach" (keyframes its ends and the middle of the plateau, within 1 cm, where the wrist or the wrists'' mean is highest); and idle segments ("action": action) for a standing lead-in and lead-out of at least 0.5 s. Replaces the automatic segments of that action and keeps every other; refuses a clip where no hand moves or the body walks, writing nothing. Returns the segments written';
REVOKE EXECUTE ON FUNCTION modb.annotate_action(bigint, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.annotate_action(bigint, text) TO modb_loader;
