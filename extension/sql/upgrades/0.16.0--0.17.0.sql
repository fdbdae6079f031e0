-- 0.17.0: hardening of the write surfaces (concurrent writes serialised, one frame-rate range and a cap
-- on the size of one result, bodies checked by type before work, messages a user can act on).
-- The PL/Python functions are re-created with the new kernel (build_sql.py).

-- Concurrent writes and caps (edit scripts, retargeting, snippet blocks).

-- End of concurrent writes and caps.


-- Validation of stored documents (joint axes, joint maps, scripts, collection paths).

-- End of validation.
