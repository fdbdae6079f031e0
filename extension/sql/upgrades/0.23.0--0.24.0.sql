-- 0.24.0: the kernel installed once per version (a package beside modb.so that the PL/Python functions
-- import), no longer pasted into every function; functions that cannot run in a parallel worker labelled so.
-- Their EXCEPTION blocks open a subtransaction, which a parallel worker cannot ("cannot start subtransactions
-- during a parallel operation"); the PL/Python functions they call are re-created below, labelled so too.
ALTER FUNCTION modb.sample_motion(text, int, int, int) PARALLEL UNSAFE;
ALTER FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8) PARALLEL UNSAFE;
