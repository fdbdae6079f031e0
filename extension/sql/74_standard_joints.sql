-- The standard joints and the dimensions of the indexed feature cube: the kernel's constants
-- (modb_kernel/joints.py), as SQL.

CREATE FUNCTION modb.standard_joints()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN {{STANDARD_JOINTS}};  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.standard_joints() IS
    'The standard joints in the order terminator arrays use (index 0 = pelvis); a joint map maps them onto a skeleton';

CREATE FUNCTION modb.feature_names()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN {{FEATURES}};  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.feature_names() IS 'The 49 dimensions of the indexed feature cube, in order (metres, m/s, and rotation-matrix entries)';
