-- How two configurations' rotations compare: the quaternion-angle operator and configuration-level
-- distances over a joint subset.

CREATE FUNCTION modb.quat_angle(aw float8, ax float8, ay float8, az float8, bw float8, bx float8, by float8, bz float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE  -- not STRICT: least() is not, and a STRICT
                                                           -- function with it in its body is never inlined
-- For unit quaternions |a-b|^2 + |a+b|^2 = 4 and a.b >= 0 exactly when |a-b| <= |a+b|, so taking the
-- smaller as the chord treats q and -q as one rotation; 4*atan2 of the chords is accurate near 0 and pi.
RETURN 4 * atan2(least(sqrt((aw - bw) ^ 2 + (ax - bx) ^ 2 + (ay - by) ^ 2 + (az - bz) ^ 2),
                       sqrt((aw + bw) ^ 2 + (ax + bx) ^ 2 + (ay + by) ^ 2 + (az + bz) ^ 2)),
                 greatest(sqrt((aw - bw) ^ 2 + (ax - bx) ^ 2 + (ay - by) ^ 2 + (az - bz) ^ 2),
                          sqrt((aw + bw) ^ 2 + (ax + bx) ^ 2 + (ay + by) ^ 2 + (az + bz) ^ 2)));
COMMENT ON FUNCTION modb.quat_angle(float8, float8, float8, float8, float8, float8, float8, float8) IS
    'Rotation angle (radians, 0..pi) between unit quaternions (aw, ax, ay, az) and (bw, bx, by, bz)';

CREATE FUNCTION modb.quat_angle(a float8[], b float8[])
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
RETURN modb.quat_angle(a[1], a[2], a[3], a[4], b[1], b[2], b[3], b[4]);
COMMENT ON FUNCTION modb.quat_angle(float8[], float8[]) IS
    'Rotation angle (radians, 0..pi) between two unit quaternions (w, x, y, z); q and -q are the same rotation';

CREATE OPERATOR modb.<%> (
    LEFTARG = float8[], RIGHTARG = float8[], FUNCTION = modb.quat_angle, COMMUTATOR = OPERATOR(modb.<%>)
);
COMMENT ON OPERATOR modb.<%> (float8[], float8[]) IS 'Rotation angle (radians) between two unit quaternions';

CREATE FUNCTION modb.max_joint_angle(a real[], b real[], joints int[])
RETURNS float8
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT max(a[4 * j + 1:4 * j + 4]::float8[] OPERATOR(modb.<%>) b[4 * j + 1:4 * j + 4]::float8[]) FROM unnest(joints) AS j;
END;
COMMENT ON FUNCTION modb.max_joint_angle(real[], real[], int[]) IS
    'Largest rotation angle between two configurations (flat arrays of (w,x,y,z) per joint) over the given joint indices (0-based)';

CREATE FUNCTION modb.weighted_joint_angle(a real[], b real[], joints int[], weights float8[])
RETURNS float8
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT sum(w * (a[4 * j + 1:4 * j + 4]::float8[] OPERATOR(modb.<%>) b[4 * j + 1:4 * j + 4]::float8[]))
      FROM unnest(joints, weights) AS t(j, w);
END;
COMMENT ON FUNCTION modb.weighted_joint_angle(real[], real[], int[], float8[]) IS
    'Weighted sum of rotation angles between two configurations over a joint subset (0-based indices, one weight each)';
