CREATE FUNCTION modb.world_positions(clip bigint, version int DEFAULT NULL)
RETURNS TABLE (frame int, joint_index int, joint text, x float8, y float8, z float8)
LANGUAGE plpython3u STABLE CALLED ON NULL INPUT PARALLEL SAFE
AS $py$
#@modb_kernel
import numpy as np
plan = GD.get("modb.world_positions plan")
if plan is None:
    plan = plpy.prepare(
        "SELECT s.hierarchy, v.rotations, v.translations FROM modb.clip_versions v "
        "JOIN modb.skeletons s ON s.id = v.skeleton_id "
        "WHERE v.clip_id = $1 AND v.version = coalesce($2, "
        "(SELECT max(version) FROM modb.clip_versions WHERE clip_id = $1))", ["bigint", "int"])
    GD["modb.world_positions plan"] = plan
rows = plpy.execute(plan, [clip, version])
if not rows:
    return []
import json
h = json.loads(rows[0]["hierarchy"])
joints = h["joints"]
positions = kernel.kinematics.world_positions(
    [j["parent"] for j in joints], [j["offset"] for j in joints],
    np.asarray(rows[0]["rotations"], dtype=np.float64),
    rows[0]["translations"], h["translated"])
names = [j["name"] for j in joints]
n_frames, n_joints = positions.shape[:2]
flat = positions.reshape(-1, 3).tolist()
return ((f, j, names[j], *flat[f * n_joints + j]) for f in range(n_frames) for j in range(n_joints))
$py$;
COMMENT ON FUNCTION modb.world_positions(bigint, int) IS
    'World positions (metres) of every joint in every frame (0-based) of a clip version (newest when NULL), by forward kinematics';
