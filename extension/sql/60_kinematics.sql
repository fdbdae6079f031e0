CREATE OR REPLACE FUNCTION modb.forward_kinematics(hierarchy jsonb, rotations real[], translations real[])
RETURNS TABLE (frame int, joint_index int, joint text, x float8, y float8, z float8)
LANGUAGE plpython3u IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
AS $py$
#@modb_kernel kinematics
import json
import numpy as np
if hierarchy is None or rotations is None:
    return []
h = json.loads(hierarchy)
joints = h["joints"]
positions = kernel.kinematics.world_positions(
    [j["parent"] for j in joints], [j["offset"] for j in joints],
    np.asarray(rotations, dtype=np.float64), translations, h["translated"])
names = [j["name"] for j in joints]
n_frames, n_joints = positions.shape[:2]
flat = positions.reshape(-1, 3).tolist()
return ((f, j, names[j], *flat[f * n_joints + j]) for f in range(n_frames) for j in range(n_joints))
$py$;
COMMENT ON FUNCTION modb.forward_kinematics(jsonb, real[], real[]) IS
    'World positions (metres) of every joint in every frame (0-based) of frames stored against a skeleton hierarchy';

CREATE FUNCTION modb.world_positions(clip bigint, version int DEFAULT NULL)
RETURNS TABLE (frame int, joint_index int, joint text, x float8, y float8, z float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT fk.*
  FROM modb.clip_versions v
  JOIN modb.skeletons s ON s.id = v.skeleton_id
 CROSS JOIN LATERAL modb.forward_kinematics(s.hierarchy, v.rotations, v.translations) AS fk
 WHERE v.clip_id = clip
   AND v.version = coalesce(world_positions.version,
                            (SELECT max(x.version) FROM modb.clip_versions x WHERE x.clip_id = clip))
$$;
COMMENT ON FUNCTION modb.world_positions(bigint, int) IS
    'World positions (metres) of every joint in every frame (0-based) of a clip version (newest when NULL), by forward kinematics';
