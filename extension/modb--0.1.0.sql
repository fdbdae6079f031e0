-- 00_header.sql
-- complain if script is sourced in psql, rather than via CREATE EXTENSION
\echo Use "CREATE EXTENSION modb CASCADE" to load this file. \quit

-- Created here, not through the control file's `schema`, so the schema is a member of the
-- extension and DROP EXTENSION removes it.
CREATE SCHEMA modb;
COMMENT ON SCHEMA modb IS 'MoDB: motion-capture clips, skeletons, collections, models and graphs';

-- 10_roles.sql
-- Roles are cluster-wide, so they are created only when missing and outlive DROP EXTENSION.
DO $$
BEGIN
    IF NOT EXISTS (SELECT FROM pg_catalog.pg_roles WHERE rolname = 'modb_reader') THEN
        CREATE ROLE modb_reader NOLOGIN;
        COMMENT ON ROLE modb_reader IS 'MoDB: read motion data (and, later, select snippets)';
    END IF;
    IF NOT EXISTS (SELECT FROM pg_catalog.pg_roles WHERE rolname = 'modb_loader') THEN
        CREATE ROLE modb_loader NOLOGIN;
        COMMENT ON ROLE modb_loader IS 'MoDB: load and edit motion data (includes modb_reader)';
    END IF;
    IF NOT pg_catalog.pg_has_role('modb_loader', 'modb_reader', 'MEMBER') THEN
        GRANT modb_reader TO modb_loader;
    END IF;
END
$$;

-- 20_validation.sql
-- Checks used by table constraints. The frame checks are numpy (one call per clip version).

CREATE OR REPLACE FUNCTION modb.unit_quaternions_ok(rotations real[], tolerance float8 DEFAULT 1e-5)
RETURNS boolean
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.1.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_1_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.1.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_1_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_1_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_1_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.1.0'] = kernel
return kernel.validate.unit_quaternions_ok(rotations, tolerance)
$py$;
COMMENT ON FUNCTION modb.unit_quaternions_ok(real[], float8) IS
    'True when every (w,x,y,z) quaternion in the array (last dimension 4) has unit length within tolerance and w >= 0';

CREATE OR REPLACE FUNCTION modb.finite_ok(elements real[])
RETURNS boolean
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.1.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_1_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.1.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_1_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_1_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_1_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.1.0'] = kernel
return kernel.validate.finite_ok(elements)
$py$;
COMMENT ON FUNCTION modb.finite_ok(real[]) IS 'True when the array holds no NULL, NaN or infinite element';

CREATE FUNCTION modb.skeleton_joint_names(hierarchy jsonb)
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY(SELECT j->>'name' FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n) ORDER BY n);
COMMENT ON FUNCTION modb.skeleton_joint_names(jsonb) IS 'Joint names of a skeleton hierarchy, in stored order';

CREATE FUNCTION modb.joint_map_ok(hierarchy jsonb, joint_map jsonb)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(joint_map) = 'object'
       AND NOT EXISTS (
           SELECT FROM jsonb_each(joint_map) AS m(standard, joint)
           WHERE m.standard <> ALL (ARRAY['pelvis', 'spine', 'chest', 'neck', 'head',
                   'left_hip', 'left_knee', 'left_ankle', 'left_toe', 'left_shoulder', 'left_elbow', 'left_wrist',
                   'right_hip', 'right_knee', 'right_ankle', 'right_toe', 'right_shoulder', 'right_elbow', 'right_wrist'])
              OR jsonb_typeof(m.joint) <> 'string'
              OR (m.joint #>> '{}') <> ALL (modb.skeleton_joint_names(hierarchy)));
END;
COMMENT ON FUNCTION modb.joint_map_ok(jsonb, jsonb) IS
    'True when joint_map maps standard joint names (pelvis, spine, chest, neck, head, left_/right_ hip, knee, ankle, toe, shoulder, elbow, wrist) onto joints of the hierarchy';

CREATE FUNCTION modb.mirror_pairs_ok(hierarchy jsonb, mirror_pairs jsonb)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(mirror_pairs) = 'array'
       AND NOT EXISTS (
           SELECT FROM jsonb_array_elements(mirror_pairs) AS p(pair)
           WHERE jsonb_typeof(p.pair) <> 'array' OR jsonb_array_length(p.pair) <> 2
              OR (p.pair->>0) = (p.pair->>1)
              OR (p.pair->>0) <> ALL (modb.skeleton_joint_names(hierarchy))
              OR (p.pair->>1) <> ALL (modb.skeleton_joint_names(hierarchy)))
       AND (SELECT count(*) = count(DISTINCT name)
              FROM jsonb_array_elements(mirror_pairs) AS p(pair),
                   LATERAL jsonb_array_elements_text(CASE WHEN jsonb_typeof(p.pair) = 'array' THEN p.pair ELSE '[]' END) AS n(name));
END;
COMMENT ON FUNCTION modb.mirror_pairs_ok(jsonb, jsonb) IS
    'True when mirror_pairs is a list of [left, right] joint-name pairs of the hierarchy, each joint in at most one pair';

CREATE FUNCTION modb.annotations_ok(meta jsonb, n_frames int)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(meta) = 'object'
       AND (NOT meta ? 'annotations' OR (
            jsonb_typeof(meta->'annotations') = 'array'
        AND NOT EXISTS (
            SELECT FROM jsonb_array_elements(meta->'annotations') AS a(seg)
            WHERE jsonb_typeof(a.seg) <> 'object'
               OR jsonb_typeof(a.seg->'name') IS DISTINCT FROM 'string'
               OR jsonb_typeof(a.seg->'start') IS DISTINCT FROM 'number'
               OR jsonb_typeof(a.seg->'end') IS DISTINCT FROM 'number'
               OR NOT ((a.seg->>'start')::numeric BETWEEN 0 AND (a.seg->>'end')::numeric)
               OR (a.seg->>'end')::numeric >= n_frames)));
END;
COMMENT ON FUNCTION modb.annotations_ok(jsonb, int) IS
    'True when meta is an object whose optional "annotations" list holds {name, start, end} segments with 0 <= start <= end < n_frames (frames, 0-based)';

CREATE FUNCTION modb.skeleton_identity(hierarchy jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- A joint whose three position channels replace its offset in every frame (Bandai stores the first
    -- frame's travel in the Hips offset) has an offset that changes no pose: leave it out, so one
    -- skeleton serves every file of a capture session.
    SELECT encode(sha256(convert_to((
        (hierarchy - 'rest_positions') || jsonb_build_object('joints', (
            SELECT jsonb_agg(CASE WHEN j->'channels' @> '["Xposition", "Yposition", "Zposition"]'
                                    OR j->'channels' @> '["TX", "TY", "TZ"]'
                                  THEN j - 'offset' ELSE j END ORDER BY n)
              FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n))))::text, 'UTF8')), 'hex');
END;
COMMENT ON FUNCTION modb.skeleton_identity(jsonb) IS
    'sha256 identifying a skeleton: its hierarchy without rest positions and without the offsets of joints whose position channels replace them';

-- 30_tables.sql
-- The motion data model, after the DFKI motion database: collections (a hierarchy),
-- skeletons, clips with immutable versions, and jsonb models and graphs.

CREATE TABLE modb.collections (
    id         bigserial PRIMARY KEY,
    parent_id  bigint REFERENCES modb.collections (id) CHECK (parent_id <> id),
    name       text NOT NULL CHECK (name ~ '^[^/]+$'),
    meta       jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at timestamptz NOT NULL DEFAULT now(),
    UNIQUE NULLS NOT DISTINCT (parent_id, name)
);
COMMENT ON TABLE modb.collections IS 'A hierarchy of collections; a path like "bandai/walks" names one';
COMMENT ON COLUMN modb.collections.parent_id IS 'Enclosing collection, NULL at the top';

CREATE TABLE modb.skeletons (
    id               bigserial PRIMARY KEY,
    name             text NOT NULL,
    hierarchy        jsonb NOT NULL CHECK (jsonb_typeof(hierarchy->'joints') = 'array'
                                           AND jsonb_array_length(hierarchy->'joints') > 0
                                           AND jsonb_typeof(hierarchy->'unit_m') = 'number'),
    identity_sha256  text NOT NULL GENERATED ALWAYS AS (modb.skeleton_identity(hierarchy)) STORED UNIQUE,
    joint_map        jsonb NOT NULL DEFAULT '{}',
    mirror_pairs     jsonb NOT NULL DEFAULT '[]',
    meta             jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at       timestamptz NOT NULL DEFAULT now(),
    CONSTRAINT skeletons_joint_map_check CHECK (modb.joint_map_ok(hierarchy, joint_map)),
    CONSTRAINT skeletons_mirror_pairs_check CHECK (modb.mirror_pairs_ok(hierarchy, mirror_pairs))
);
COMMENT ON TABLE modb.skeletons IS
    'Joint hierarchies as loaded; hierarchies equal up to offsets their position channels replace are stored once (identity_sha256)';
COMMENT ON COLUMN modb.skeletons.hierarchy IS
    'Immutable: {"format", "unit_m" (metres per source unit), "joints": [{"name", "parent" (index, -1 for the root), "offset" (metres), "channels" (as loaded), "rotation_order", "end_site"}], "translated" (indices of joints with position channels), "rest_positions" (metres)}';
COMMENT ON COLUMN modb.skeletons.joint_map IS
    'Editable: standard joint name (pelvis, spine, chest, neck, head, left_/right_ hip, knee, ankle, toe, shoulder, elbow, wrist) -> joint name; pelvis carries the body''s travel';
COMMENT ON COLUMN modb.skeletons.mirror_pairs IS 'Editable: [[left, right], ...] for every sided joint, used for mirroring';

CREATE TABLE modb.clips (
    id            bigserial PRIMARY KEY,
    collection_id bigint NOT NULL REFERENCES modb.collections (id),
    name          text NOT NULL CHECK (name <> ''),
    meta          jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at    timestamptz NOT NULL DEFAULT now(),
    UNIQUE (collection_id, name)
);
COMMENT ON TABLE modb.clips IS 'A clip''s identity; its motion is in modb.clip_versions, the newest version being "the clip"';

CREATE TABLE modb.clip_versions (
    clip_id       bigint NOT NULL REFERENCES modb.clips (id) ON DELETE CASCADE,
    version       int NOT NULL CHECK (version > 0),
    skeleton_id   bigint NOT NULL REFERENCES modb.skeletons (id),
    fps           float8 NOT NULL CHECK (fps > 0 AND fps < 'Infinity'),
    n_frames      int NOT NULL CHECK (n_frames > 0),
    rotations     real[] NOT NULL,
    translations  real[],
    source_file   text,
    source_sha256 text CHECK (source_sha256 ~ '^[0-9a-f]{64}$'),
    load_params   jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(load_params) = 'object'),
    meta          jsonb NOT NULL DEFAULT '{}',
    created_at    timestamptz NOT NULL DEFAULT now(),
    created_by    name NOT NULL DEFAULT current_user,
    PRIMARY KEY (clip_id, version),
    CONSTRAINT clip_versions_rotations_shape_check CHECK (
        array_ndims(rotations) = 3 AND array_length(rotations, 1) = n_frames AND array_length(rotations, 3) = 4),
    CONSTRAINT clip_versions_translations_shape_check CHECK (translations IS NULL OR (
        array_ndims(translations) = 3 AND array_length(translations, 1) = n_frames AND array_length(translations, 3) = 3)),
    CONSTRAINT clip_versions_rotations_unit_check CHECK (modb.unit_quaternions_ok(rotations, 1e-5)),
    CONSTRAINT clip_versions_translations_finite_check CHECK (translations IS NULL OR modb.finite_ok(translations)),
    CONSTRAINT clip_versions_meta_check CHECK (modb.annotations_ok(meta, n_frames))
);
COMMENT ON TABLE modb.clip_versions IS
    'Immutable versions of a clip''s motion (only meta may change); re-loading a changed file or editing adds a version';
COMMENT ON COLUMN modb.clip_versions.rotations IS
    'real[n_frames][n_joints][4]: per frame and joint a unit quaternion (w, x, y, z), w >= 0, relative to the parent, joints in skeleton order';
COMMENT ON COLUMN modb.clip_versions.translations IS
    'real[n_frames][n_translated][3]: local translation in metres of each joint with position channels (skeleton hierarchy->translated), replacing its offset; NULL when none';
COMMENT ON COLUMN modb.clip_versions.source_sha256 IS 'sha256 of the source file; loading an unchanged file again stores nothing';
COMMENT ON COLUMN modb.clip_versions.load_params IS 'How the file was read: units rule, metres per unit, frame time';
COMMENT ON COLUMN modb.clip_versions.meta IS
    'Editable: {"annotations": [{"name", "start", "end"} (frames, 0-based, inclusive)], "tags": [...], ...}';

CREATE TABLE modb.models (
    id          bigserial PRIMARY KEY,
    name        text NOT NULL,
    kind        text NOT NULL,
    skeleton_id bigint REFERENCES modb.skeletons (id),
    data        jsonb NOT NULL,
    meta        jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at  timestamptz NOT NULL DEFAULT now(),
    UNIQUE (name, kind)
);
COMMENT ON TABLE modb.models IS 'Statistical motion models (jsonb), by name and kind';

CREATE TABLE modb.graphs (
    id          bigserial PRIMARY KEY,
    name        text NOT NULL,
    kind        text NOT NULL,
    skeleton_id bigint REFERENCES modb.skeletons (id),
    data        jsonb NOT NULL,
    meta        jsonb NOT NULL DEFAULT '{}' CHECK (jsonb_typeof(meta) = 'object'),
    created_at  timestamptz NOT NULL DEFAULT now(),
    UNIQUE (name, kind)
);
COMMENT ON TABLE modb.graphs IS 'Motion graphs (jsonb), by name and kind';

CREATE INDEX clip_versions_skeleton_idx ON modb.clip_versions (skeleton_id);
CREATE INDEX clip_versions_sha256_idx ON modb.clip_versions (source_sha256);
CREATE INDEX clips_collection_idx ON modb.clips (collection_id);

-- pg_dump keeps the data of extension tables only when they are registered here;
-- the sequences too, so ids issued after a restore do not collide.
SELECT pg_catalog.pg_extension_config_dump('modb.collections', '');
SELECT pg_catalog.pg_extension_config_dump('modb.collections_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.skeletons', '');
SELECT pg_catalog.pg_extension_config_dump('modb.skeletons_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clips', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clips_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.clip_versions', '');
SELECT pg_catalog.pg_extension_config_dump('modb.models', '');
SELECT pg_catalog.pg_extension_config_dump('modb.models_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.graphs', '');
SELECT pg_catalog.pg_extension_config_dump('modb.graphs_id_seq', '');

-- 40_clip_rules.sql
-- Rules a constraint cannot express: frame layout against the skeleton, version numbering, immutability.

CREATE FUNCTION modb.clip_versions_before_insert()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    h jsonb;
    n_translated int;
BEGIN
    SELECT hierarchy INTO h FROM modb.skeletons WHERE id = NEW.skeleton_id;
    IF array_length(NEW.rotations, 2) IS DISTINCT FROM jsonb_array_length(h->'joints') THEN
        RAISE EXCEPTION 'rotations has % joints, skeleton % has %',
            array_length(NEW.rotations, 2), NEW.skeleton_id, jsonb_array_length(h->'joints')
            USING ERRCODE = 'check_violation',
                  HINT = 'rotations is real[n_frames][n_joints][4] with the joints in skeleton order';
    END IF;
    n_translated := coalesce(jsonb_array_length(h->'translated'), 0);
    IF coalesce(array_length(NEW.translations, 2), 0) <> n_translated THEN
        RAISE EXCEPTION 'translations has % joints, skeleton % has % joints with position channels',
            coalesce(array_length(NEW.translations, 2), 0), NEW.skeleton_id, n_translated
            USING ERRCODE = 'check_violation',
                  HINT = 'translations is real[n_frames][n_translated][3], NULL when no joint has position channels';
    END IF;
    IF NEW.version IS NULL THEN
        SELECT coalesce(max(version), 0) + 1 INTO NEW.version FROM modb.clip_versions WHERE clip_id = NEW.clip_id;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_before_insert() IS
    'Trigger: checks the frame arrays against the skeleton and numbers the version (newest + 1) when not given';

CREATE TRIGGER clip_versions_before_insert BEFORE INSERT ON modb.clip_versions
    FOR EACH ROW EXECUTE FUNCTION modb.clip_versions_before_insert();

CREATE FUNCTION modb.clip_versions_before_update()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF (NEW.clip_id, NEW.version, NEW.skeleton_id, NEW.fps, NEW.n_frames, NEW.rotations, NEW.translations,
        NEW.source_file, NEW.source_sha256, NEW.load_params, NEW.created_at, NEW.created_by)
       IS DISTINCT FROM
       (OLD.clip_id, OLD.version, OLD.skeleton_id, OLD.fps, OLD.n_frames, OLD.rotations, OLD.translations,
        OLD.source_file, OLD.source_sha256, OLD.load_params, OLD.created_at, OLD.created_by) THEN
        RAISE EXCEPTION 'clip % version % is immutable: only meta may change', OLD.clip_id, OLD.version
            USING ERRCODE = 'object_not_in_prerequisite_state',
                  HINT = 'insert a new version instead (modb load adds one when the file changed)';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_before_update() IS 'Trigger: a clip version''s motion is immutable, only meta may change';

CREATE TRIGGER clip_versions_before_update BEFORE UPDATE ON modb.clip_versions
    FOR EACH ROW EXECUTE FUNCTION modb.clip_versions_before_update();

CREATE FUNCTION modb.skeletons_before_update()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF NEW.hierarchy IS DISTINCT FROM OLD.hierarchy THEN
        RAISE EXCEPTION 'the hierarchy of skeleton % is immutable: clips are stored against it', OLD.id
            USING ERRCODE = 'object_not_in_prerequisite_state',
                  HINT = 'load the motion again with the changed skeleton; joint_map, mirror_pairs, name and meta may be edited';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.skeletons_before_update() IS
    'Trigger: a skeleton''s hierarchy is immutable (its clips'' frames follow it); the joint map and pairs may change';

CREATE TRIGGER skeletons_before_update BEFORE UPDATE ON modb.skeletons
    FOR EACH ROW EXECUTE FUNCTION modb.skeletons_before_update();

-- 50_collections.sql
CREATE FUNCTION modb.collection_path(collection bigint)
RETURNS text
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    WITH RECURSIVE up(id, parent_id, name, depth) AS (
        SELECT id, parent_id, name, 0 FROM modb.collections WHERE id = collection
        UNION ALL
        SELECT c.id, c.parent_id, c.name, up.depth + 1 FROM modb.collections c JOIN up ON c.id = up.parent_id
         WHERE up.depth < 1000  -- a parent_id cycle, which only the owner can create, must not recurse forever
    )
    SELECT string_agg(name, '/' ORDER BY depth DESC) FROM up;
END;
COMMENT ON FUNCTION modb.collection_path(bigint) IS 'The path "a/b/c" of a collection, NULL for an unknown id';

CREATE FUNCTION modb.find_collection(path text)
RETURNS bigint
LANGUAGE plpgsql STABLE STRICT PARALLEL SAFE
AS $$
DECLARE
    part text;
    current bigint := NULL;
BEGIN
    FOREACH part IN ARRAY string_to_array(trim(BOTH '/' FROM path), '/') LOOP
        SELECT id INTO current FROM modb.collections
         WHERE parent_id IS NOT DISTINCT FROM current AND name = part;
        IF NOT FOUND THEN
            RETURN NULL;
        END IF;
    END LOOP;
    RETURN current;
END
$$;
COMMENT ON FUNCTION modb.find_collection(text) IS 'The id of the collection at path "a/b/c", NULL when absent';

CREATE FUNCTION modb.ensure_collection(path text)
RETURNS bigint
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    part text;
    current bigint := NULL;
    found_id bigint;
BEGIN
    IF trim(BOTH '/' FROM path) = '' THEN
        RAISE EXCEPTION 'collection path is empty' USING HINT = 'give a path like "bandai/walks"';
    END IF;
    FOREACH part IN ARRAY string_to_array(trim(BOTH '/' FROM path), '/') LOOP
        IF part = '' THEN
            RAISE EXCEPTION 'collection path "%" has an empty part', path USING HINT = 'remove the doubled "/"';
        END IF;
        INSERT INTO modb.collections (parent_id, name) VALUES (current, part)
            ON CONFLICT (parent_id, name) DO NOTHING
            RETURNING id INTO found_id;
        IF found_id IS NULL THEN
            SELECT id INTO found_id FROM modb.collections WHERE parent_id IS NOT DISTINCT FROM current AND name = part;
        END IF;
        current := found_id;
        found_id := NULL;
    END LOOP;
    RETURN current;
END
$$;
COMMENT ON FUNCTION modb.ensure_collection(text) IS 'The id of the collection at path "a/b/c", creating missing levels';

CREATE VIEW modb.current_clips AS
SELECT c.id AS clip_id,
       c.name,
       modb.collection_path(c.collection_id) AS collection,
       v.version,
       v.skeleton_id,
       v.fps,
       v.n_frames,
       v.n_frames / v.fps AS seconds,
       v.source_file,
       v.source_sha256,
       v.meta,
       v.created_at
  FROM modb.clips c
  JOIN LATERAL (SELECT * FROM modb.clip_versions cv WHERE cv.clip_id = c.id ORDER BY cv.version DESC LIMIT 1) v ON true;
COMMENT ON VIEW modb.current_clips IS 'Every clip with its newest version ("the clip" unless a version is named)';

-- 60_kinematics.sql
CREATE OR REPLACE FUNCTION modb.forward_kinematics(hierarchy jsonb, rotations real[], translations real[])
RETURNS TABLE (frame int, joint_index int, joint text, x float8, y float8, z float8)
LANGUAGE plpython3u IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.1.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_1_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.1.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_1_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_1_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_1_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.1.0'] = kernel
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

-- 90_privileges.sql
-- Least privilege: modb_reader reads, modb_loader (a member of modb_reader) writes.
GRANT USAGE ON SCHEMA modb TO modb_reader, modb_loader;
GRANT SELECT ON ALL TABLES IN SCHEMA modb TO modb_reader;
GRANT INSERT ON modb.collections, modb.skeletons, modb.clips, modb.clip_versions TO modb_loader;
GRANT UPDATE (meta) ON modb.collections, modb.clips, modb.clip_versions TO modb_loader;
GRANT UPDATE (name, joint_map, mirror_pairs, meta) ON modb.skeletons TO modb_loader;
GRANT INSERT, UPDATE, DELETE ON modb.models, modb.graphs TO modb_loader;
GRANT USAGE ON ALL SEQUENCES IN SCHEMA modb TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.ensure_collection(text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.ensure_collection(text) TO modb_loader;
