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
kernel = GD.get('modb_kernel 0.7.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.cost_to_go': '"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of graph\nsnippets needs from that snippet\'s end until the pelvis is within the arrival radius of a goal, for goals\non a polar grid around that end (in its heading frame: x left, z forward).\n\nWhy: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind the\navatar when every successor of a straight walk goes straight, and circles a near goal. The cost-to-go\ncounts the turns the data can make after the candidate, however many snippets they take (as in\nnear-optimal controllers over motion graphs), so select_next_snippet\'s stored-transition level ranks by\n"seconds to the goal through this candidate" in one indexed lookup per candidate.\n\nComputed by value iteration (Bellman): V(s, g) = min over successors t of s of\nduration(t) + seam(s, t) + V(t, g seen from t\'s end), V = 0 within the arrival radius. seam(s, t) is the\ntransition\'s continuity ratio times the profile\'s continuity_weight / speed: the price the selection puts on\na rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals are read by\nbilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring\'s value plus the\nextra distance at the graph\'s median speed. The SQL reader is modb.cost_to_go, the same arithmetic.\n"""\nfrom dataclasses import asdict, dataclass\n\nimport numpy as np\n\nTOLERANCE = 0.01  # seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of convergence)\nMAX_ITERATIONS = 300\nMIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move\nEDGE_CHUNK = 4000  # sources per gather: bounds memory at about chunk x mean out-degree x grid size\n\n\n@dataclass(frozen=True)\nclass Grid:\n    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left) times\n    `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices the distance\n    beyond the outer ring. Values are stored angle-major: index angle * rings + ring."""\n    speed: float\n    angles: int = 24\n    rings: int = 11\n    inner_radius: float = 0.5\n    outer_radius: float = 12.0\n\n    def radii(self) -> np.ndarray:\n        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (np.arange(self.rings) / (self.rings - 1))\n\n    def points(self) -> tuple[np.ndarray, np.ndarray]:\n        """(x, z) of every grid point, in storage order."""\n        theta = np.arange(self.angles) * 2 * np.pi / self.angles\n        r = self.radii()\n        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()\n\n    def as_json(self) -> dict:\n        return asdict(self)\n\n\ndef interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):\n    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds added\n    beyond the outer ring. Goals within the inner radius get weights 0: reached."""\n    r = np.hypot(x, z)\n    ring = np.log(np.maximum(r, 1e-9) / grid.inner_radius) / np.log(grid.outer_radius / grid.inner_radius) * (grid.rings - 1)\n    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)\n    j0 = np.floor(ring).astype(np.int64)\n    wj = ring - j0\n    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)\n    a0 = np.floor(angle).astype(np.int64) % grid.angles\n    a1 = (a0 + 1) % grid.angles\n    wa = angle - np.floor(angle)\n    index = np.stack([a0 * grid.rings + j0, a0 * grid.rings + j0 + 1, a1 * grid.rings + j0, a1 * grid.rings + j0 + 1], -1)\n    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)\n    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed\n    reached = r <= grid.inner_radius\n    weight[reached] = 0\n    beyond[reached] = 0\n    return index, weight.astype(np.float32), beyond.astype(np.float32)\n\n\ndef seen_from_end(net_x, net_z, heading, x, z):\n    """Points (x, z) of a snippet\'s start frame seen from its end (modb.world_to_local): per snippet rows."""\n    dx = x[None, :] - np.asarray(net_x)[:, None]\n    dz = z[None, :] - np.asarray(net_z)[:, None]\n    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]\n    return dx * c - dz * s, dx * s + dz * c\n\n\ndef cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):\n    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.\n    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides the\n    duration of dst; a snippet without successors gets infinity."""\n    n = len(duration)\n    size = grid.angles * grid.rings\n    gx, gz = grid.points()\n    index, weight, beyond = interpolation(grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz))\n    index += (np.arange(n) * size)[:, None, None]  # into the flattened values\n    duration = np.asarray(duration, dtype=np.float32)[:, None]\n    order = np.argsort(src, kind="stable")\n    src, dst = np.asarray(src)[order], np.asarray(dst)[order]\n    seam = np.asarray(seam, dtype=np.float32)[order][:, None]\n    starts = np.r_[0, np.flatnonzero(np.diff(src)) + 1] if len(src) else np.zeros(0, dtype=np.int64)\n    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0\n    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.\n    values = np.tile(np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)).astype(np.float32)\n    values[:, ring0] = 0\n    change = np.inf\n    for iteration in range(1, MAX_ITERATIONS + 1):\n        through = duration + (values.ravel()[index] * weight).sum(-1) + beyond  # via each snippet as the next\n        new = np.full_like(values, np.inf)\n        for lo in range(0, len(starts), EDGE_CHUNK):\n            first = starts[lo:lo + EDGE_CHUNK]\n            stop = starts[lo + EDGE_CHUNK] if lo + EDGE_CHUNK < len(starts) else len(src)\n            new[src[first]] = np.minimum.reduceat(through[dst[first[0]:stop]] + seam[first[0]:stop], first - first[0], axis=0)\n        new[:, ring0] = 0\n        finite = np.isfinite(new)\n        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0\n        values = new\n        if progress:\n            progress(iteration, change)\n        if change < TOLERANCE:\n            break\n    return values, iteration, change\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The mirrored\njoint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how m(c)\'s frame sits\nagainst c\'s in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c (S R_root M_root at the\nroot), and a translated joint\'s translation becomes M_j t (S t at the root). Positions are exact whatever\nM is, as far as the captured skeleton is symmetric; rotations are what the same rig would report for the\nmirrored motion only with the rig\'s own M, and only then can mirrored snippets follow captured ones.\n\nFinding M_c. Every candidate must map c\'s child offsets (and end site, and translations that never change)\nonto its partner\'s: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates are the 24\nsigned permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where that leaves a choice\n(a bone\'s twist is invisible in its offsets):\n- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body\'s left-right axis as\n  seen in that frame (the principal axis of the hips\' and clavicles\' separations over the clip, which no yaw\n  or gesture changes) if it lies within 30 degrees of one; else, as in a joint that does not turn with the\n  body (a root above the pelvis), or a head held turned for a whole clip, it keeps its parent\'s;\n- a paired joint keeps its parent\'s M where that fits (a rig whose frames follow its symmetry: CMU\'s ASF,\n  S everywhere), else -I where that fits (a Maya-style rig mirrors the right side\'s axes as a whole);\n- anything else takes the candidate whose mirrored rotations come nearest, on average, to the partner\'s.\nA rig that is not axis-aligned gets the best fit of its offsets instead.\n"""\nimport itertools\n\nimport numpy as np\n\nfrom . import kinematics, quaternion\n\nWORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])\n# A captured skeleton\'s two sides differ by a few degrees (CMU 131\'s neck leans 7 degrees): within this the\n# axis-aligned convention is taken as the rig\'s, and the difference as capture asymmetry.\nALIGNED_COS = np.cos(np.radians(15.0))\nLATERAL_STEADINESS = 0.8  # share of the separations\' spread along the axis it takes to be one\nSTEADY_TRANSLATION = 1e-3  # relative spread under which a translation channel counts as a fixed offset\n\n\ndef _axis_aligned_reflections():\n    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror convention."""\n    out = []\n    for perm in itertools.permutations(range(3)):\n        for signs in itertools.product((1.0, -1.0), repeat=3):\n            m = np.zeros((3, 3))\n            m[list(perm), range(3)] = signs\n            if np.linalg.det(m) < 0:\n                out.append(m)\n    return out\n\n\nCANDIDATES = _axis_aligned_reflections()\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _unit(v):\n    v = np.asarray(v, dtype=np.float64)\n    norm = np.linalg.norm(v)\n    return v / norm if norm > 1e-9 else None\n\n\ndef _flips_one_axis(m):\n    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)\n\n\ndef _turning(a, b):\n    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when opposite)."""\n    axis = np.cross(a, b)\n    s, c = np.linalg.norm(axis), float(np.dot(a, b))\n    if s < 1e-12:\n        if c > 0:\n            return np.eye(3)\n        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0\n    axis = axis / np.linalg.norm(axis)\n    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])\n    return np.eye(3) + s * k + (1.0 - c) * (k @ k)\n\n\ndef _improper_fit(sources, targets):\n    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets (Kabsch)."""\n    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))\n    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt\n\n\ndef _fixed_offsets(offsets, translations, translated):\n    """Offsets, with those of translated joints whose translation never changes taken from it."""\n    offsets = np.array(offsets, dtype=np.float64)\n    for k, j in enumerate(translated):\n        t = np.asarray(translations, dtype=np.float64)[:, k]\n        mean = t.mean(axis=0)\n        offsets[j] = mean if np.abs(t - mean).max() <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0\n    return offsets\n\n\ndef _direction_pairs(j, children, offsets, end_sites, partner):\n    """(direction, partner\'s direction) of j\'s child offsets and end site, where both are non-zero."""\n    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]\n    if end_sites[j] is not None and end_sites[partner[j]] is not None:\n        pairs.append((end_sites[j], end_sites[partner[j]]))\n    units = [(_unit(a), _unit(b)) for a, b in pairs]\n    return [(a, b) for a, b in units if a is not None and b is not None]\n\n\ndef _lateral_axes(parents, positions, orientations, partner):\n    """Per joint, the body\'s left-right axis in the joint\'s own frame: the principal axis of the separations\n    of the pairs hung from one unpaired parent (hips, clavicles; or the first pair below them that is apart),\n    over all frames; zero where no axis holds (a root above the pelvis that does not turn with the body)."""\n    pairs = []\n    for c, m in enumerate(partner):\n        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:\n            while np.linalg.norm(positions[:, c] - positions[:, m], axis=-1).mean() < 1e-3:  # CMU\'s hip joints\n                below = [k for k in range(len(parents)) if parents[k] == c]\n                if not below:\n                    break\n                c, m = below[0], partner[below[0]]\n            pairs.append((c, m))\n    if not pairs:\n        return np.zeros((len(parents), 3))\n    separation = positions[:, [c for c, _ in pairs]] - positions[:, [m for _, m in pairs]]  # (F, P, 3)\n    separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)\n    local = quaternion.rotate(quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :])\n    values, vectors = np.linalg.eigh(np.einsum("fjpa,fjpb->jab", local, local))  # (J, 3, 3) scatter\n    steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)\n    turning = np.abs(orientations - orientations[:1]).max(axis=(0, 2)) > 1e-9  # a fixed frame is the world\'s\n    return vectors[:, :, -1] * (steady & turning)[:, None]\n\n\ndef _nearest_flip(candidates, axis):\n    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned for a\n    whole clip is no evidence of its frame)."""\n    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|\n    return best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None\n\n\ndef frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):\n    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3); mean_rotations:\n    (J, 3, 3) averages of the clip\'s parent-relative rotation matrices."""\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    out = np.empty((n_joints, 3, 3))\n    for j in range(n_joints):  # parents come before children\n        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one\'s\n            out[j] = out[partner[j]].T\n            continue\n        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]\n        pairs = _direction_pairs(j, children, offsets, end_sites, partner)\n        candidates = [m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)]\n        if partner[j] == j:\n            candidates = [m for m in candidates if _flips_one_axis(m)]\n        if not candidates:  # not axis-aligned: fit the offsets\n            sources = np.array([a for a, _ in pairs])\n            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:\n                out[j] = _improper_fit(sources, [b for _, b in pairs])\n                continue\n            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]\n        if len(candidates) == 1:\n            out[j] = candidates[0]\n        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:\n            out[j] = flip\n        elif any(np.allclose(m, above) for m in candidates):\n            out[j] = above\n        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):\n            out[j] = -np.eye(3)\n        else:\n            target = mean_rotations[partner[j]]\n            out[j] = min(candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target))\n    return out\n\n\ndef clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """M_j of every joint, found from a clip of the skeleton (see the module docstring)."""\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    return frame_reflections(parents, _fixed_offsets(offsets, translations, translated), end_sites, partner,\n                             _lateral_axes(parents, positions, orientations, partner),\n                             quaternion.to_matrix(rotations).mean(axis=0))\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    frames = clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated)\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = WORLD_REFLECTION if p < 0 else frames[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])\n    if not len(translated):\n        return out_rotations, translations\n    translations = np.asarray(translations, dtype=np.float64)\n    out_translations = np.empty_like(translations)\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]\n        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef conjugate(q):\n    """The inverse of unit quaternions: the same axis, the opposite angle."""\n    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = quaternion.conjugate(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.transitions': '"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and the\npart of it a chain can keep moving and steering in: the largest strongly connected component (as in\nmotion graphs) that holds turns both ways.\n\nOutside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a\ncomponent it cannot leave that never turns (in Bandai dataset 2, the runs: from a run\'s end only runs\npass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to the\nsteerable component keeps every chain where it can face its next goal.\n\nThe edge test is select_next_snippets\' level 0, computed for all pairs at once: the same search box\naround the end\'s features, the same per-joint ratio (position by the norm, rotation angle, velocities)\nwith the same float4 arithmetic, and the same rule against replaying the previous snippet\'s frames.\nNeeds scipy (the server: Debian\'s python3-scipy) for the box search and the components.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\nBOX_MARGIN = 1e-4  # match_box\'s margin: terminators store float4, features float8\n\n\nclass Terminators:\n    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19, 4)\n    as stored (float4), and features (n, 25)."""\n\n    def __init__(self, positions, rotations, velocities, angular_velocities, features):\n        n = len(features)\n        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)\n        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)\n        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)\n\n\ndef _norm(a, b, norm):\n    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens\n    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))\n\n\ndef _joint_terms(term, src, dst, plan, j):\n    """Joint j\'s continuity terms for pairs (end terminator src[k], begin terminator dst[k]): (difference,\n    threshold) for the rotation angle, the position (the plan\'s norm) and, with velocity terms, the\n    velocity and angular velocity."""\n    yield quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]), plan["angle_threshold"][j]\n    yield _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]), plan["position_threshold"][j]\n    if plan["velocity_terms"]:\n        yield _norm(term.velocities[src, j], term.velocities[dst, j], "l2"), plan["velocity_threshold"][j]\n        yield (_norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),\n               plan["angular_velocity_threshold"][j])\n\n\ndef _within(term, src, dst, plan):\n    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio is at\n    most 1. Joint by joint, the tightest first, so most pairs are dropped after one or two joints."""\n    keep = np.ones(len(src), dtype=bool)\n    order = sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j])\n    for j in order:\n        s, d = src[keep], dst[keep]\n        ok = np.ones(len(s), dtype=bool)\n        for difference, threshold in _joint_terms(term, s, d, plan, j):\n            ok &= difference <= threshold\n        keep[np.flatnonzero(keep)[~ok]] = False\n    return keep\n\n\ndef ratios(term, src, dst, plan):\n    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest over the\n    plan\'s joints and terms of difference / threshold (select_next_snippets\' continuity_ratio)."""\n    ratio = np.zeros(len(src))\n    for j in plan["joints"]:\n        for difference, threshold in _joint_terms(term, src, dst, plan, j):\n            ratio = np.maximum(ratio, difference / threshold)\n    return ratio\n\n\ndef edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):\n    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets given by\n    their begin and end terminator rows in `term`, their pose/rate group, clip (and version, mirror: one key)\n    and window. progress(done) is called after each chunk of sources."""\n    from scipy.spatial import cKDTree\n\n    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN\n    out_src, out_dst, out_ratio = [], [], []\n    done = 0\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        tree = cKDTree(term.features[begin[members]] / half)\n        for lo in range(0, len(members), chunk):\n            sources = members[lo:lo + chunk]\n            done += len(sources)\n            near = tree.query_ball_point(term.features[end[sources]] / half, r=1.0, p=np.inf)\n            counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))\n            if not counts.sum():\n                continue  # (progress is reported with the next chunk that has candidates)\n            s = np.repeat(sources, counts)\n            d = members[np.concatenate([np.asarray(c, dtype=np.int64) for c in near if len(c)])]\n            # No replay of the previous snippet\'s frames (its last frame, the seam, aside).\n            overlap = ((clip[s] == clip[d]) & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)\n                       & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1))\n            s, d = s[~overlap], d[~overlap]\n            keep = _within(term, end[s], begin[d], plan)\n            out_src.append(s[keep])\n            out_dst.append(d[keep])\n            out_ratio.append(ratios(term, end[s[keep]], begin[d[keep]], plan))\n            if progress:\n                progress(done)\n    if not out_src:\n        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)\n    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)\n\n\ndef steerable(n, src, dst, group, turn, min_turn):\n    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate group\n    among those (of more than one snippet) whose snippets include turns of at least min_turn radians each\n    way (`turn`: the heading change where each one leads). A chain in it can always move on, and can face\n    any goal. (The largest only, as in motion graphs: on Bandai dataset 2, adding the active walks\'\n    component to the slow walks\' made right-angle courses worse: README "Transition graphs".)"""\n    from scipy.sparse import coo_matrix\n    from scipy.sparse.csgraph import connected_components\n\n    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()\n    _, label = connected_components(graph, directed=True, connection="strong")\n    turn = np.asarray(turn, dtype=np.float64)\n    size = np.bincount(label, minlength=label.max() + 1)\n    left = np.zeros(len(size), dtype=bool)\n    right = np.zeros(len(size), dtype=bool)\n    np.logical_or.at(left, label, turn >= min_turn)\n    np.logical_or.at(right, label, turn <= -min_turn)\n    eligible = (size > 1) & left & right\n    keep = np.zeros(n, dtype=bool)\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        candidates = np.unique(label[members][eligible[label[members]]])\n        if len(candidates):\n            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True\n    return keep\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_7_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.7.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_7_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_7_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_7_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.7.0'] = kernel
return kernel.validate.unit_quaternions_ok(rotations, tolerance)
$py$;
COMMENT ON FUNCTION modb.unit_quaternions_ok(real[], float8) IS
    'True when every (w,x,y,z) quaternion in the array (last dimension 4) has unit length within tolerance and w >= 0';

CREATE OR REPLACE FUNCTION modb.finite_ok(elements real[])
RETURNS boolean
LANGUAGE plpython3u IMMUTABLE STRICT PARALLEL SAFE
AS $py$
kernel = GD.get('modb_kernel 0.7.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.cost_to_go': '"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of graph\nsnippets needs from that snippet\'s end until the pelvis is within the arrival radius of a goal, for goals\non a polar grid around that end (in its heading frame: x left, z forward).\n\nWhy: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind the\navatar when every successor of a straight walk goes straight, and circles a near goal. The cost-to-go\ncounts the turns the data can make after the candidate, however many snippets they take (as in\nnear-optimal controllers over motion graphs), so select_next_snippet\'s stored-transition level ranks by\n"seconds to the goal through this candidate" in one indexed lookup per candidate.\n\nComputed by value iteration (Bellman): V(s, g) = min over successors t of s of\nduration(t) + seam(s, t) + V(t, g seen from t\'s end), V = 0 within the arrival radius. seam(s, t) is the\ntransition\'s continuity ratio times the profile\'s continuity_weight / speed: the price the selection puts on\na rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals are read by\nbilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring\'s value plus the\nextra distance at the graph\'s median speed. The SQL reader is modb.cost_to_go, the same arithmetic.\n"""\nfrom dataclasses import asdict, dataclass\n\nimport numpy as np\n\nTOLERANCE = 0.01  # seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of convergence)\nMAX_ITERATIONS = 300\nMIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move\nEDGE_CHUNK = 4000  # sources per gather: bounds memory at about chunk x mean out-degree x grid size\n\n\n@dataclass(frozen=True)\nclass Grid:\n    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left) times\n    `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices the distance\n    beyond the outer ring. Values are stored angle-major: index angle * rings + ring."""\n    speed: float\n    angles: int = 24\n    rings: int = 11\n    inner_radius: float = 0.5\n    outer_radius: float = 12.0\n\n    def radii(self) -> np.ndarray:\n        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (np.arange(self.rings) / (self.rings - 1))\n\n    def points(self) -> tuple[np.ndarray, np.ndarray]:\n        """(x, z) of every grid point, in storage order."""\n        theta = np.arange(self.angles) * 2 * np.pi / self.angles\n        r = self.radii()\n        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()\n\n    def as_json(self) -> dict:\n        return asdict(self)\n\n\ndef interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):\n    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds added\n    beyond the outer ring. Goals within the inner radius get weights 0: reached."""\n    r = np.hypot(x, z)\n    ring = np.log(np.maximum(r, 1e-9) / grid.inner_radius) / np.log(grid.outer_radius / grid.inner_radius) * (grid.rings - 1)\n    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)\n    j0 = np.floor(ring).astype(np.int64)\n    wj = ring - j0\n    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)\n    a0 = np.floor(angle).astype(np.int64) % grid.angles\n    a1 = (a0 + 1) % grid.angles\n    wa = angle - np.floor(angle)\n    index = np.stack([a0 * grid.rings + j0, a0 * grid.rings + j0 + 1, a1 * grid.rings + j0, a1 * grid.rings + j0 + 1], -1)\n    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)\n    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed\n    reached = r <= grid.inner_radius\n    weight[reached] = 0\n    beyond[reached] = 0\n    return index, weight.astype(np.float32), beyond.astype(np.float32)\n\n\ndef seen_from_end(net_x, net_z, heading, x, z):\n    """Points (x, z) of a snippet\'s start frame seen from its end (modb.world_to_local): per snippet rows."""\n    dx = x[None, :] - np.asarray(net_x)[:, None]\n    dz = z[None, :] - np.asarray(net_z)[:, None]\n    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]\n    return dx * c - dz * s, dx * s + dz * c\n\n\ndef cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):\n    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.\n    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides the\n    duration of dst; a snippet without successors gets infinity."""\n    n = len(duration)\n    size = grid.angles * grid.rings\n    gx, gz = grid.points()\n    index, weight, beyond = interpolation(grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz))\n    index += (np.arange(n) * size)[:, None, None]  # into the flattened values\n    duration = np.asarray(duration, dtype=np.float32)[:, None]\n    order = np.argsort(src, kind="stable")\n    src, dst = np.asarray(src)[order], np.asarray(dst)[order]\n    seam = np.asarray(seam, dtype=np.float32)[order][:, None]\n    starts = np.r_[0, np.flatnonzero(np.diff(src)) + 1] if len(src) else np.zeros(0, dtype=np.int64)\n    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0\n    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.\n    values = np.tile(np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)).astype(np.float32)\n    values[:, ring0] = 0\n    change = np.inf\n    for iteration in range(1, MAX_ITERATIONS + 1):\n        through = duration + (values.ravel()[index] * weight).sum(-1) + beyond  # via each snippet as the next\n        new = np.full_like(values, np.inf)\n        for lo in range(0, len(starts), EDGE_CHUNK):\n            first = starts[lo:lo + EDGE_CHUNK]\n            stop = starts[lo + EDGE_CHUNK] if lo + EDGE_CHUNK < len(starts) else len(src)\n            new[src[first]] = np.minimum.reduceat(through[dst[first[0]:stop]] + seam[first[0]:stop], first - first[0], axis=0)\n        new[:, ring0] = 0\n        finite = np.isfinite(new)\n        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0\n        values = new\n        if progress:\n            progress(iteration, change)\n        if change < TOLERANCE:\n            break\n    return values, iteration, change\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The mirrored\njoint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how m(c)\'s frame sits\nagainst c\'s in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c (S R_root M_root at the\nroot), and a translated joint\'s translation becomes M_j t (S t at the root). Positions are exact whatever\nM is, as far as the captured skeleton is symmetric; rotations are what the same rig would report for the\nmirrored motion only with the rig\'s own M, and only then can mirrored snippets follow captured ones.\n\nFinding M_c. Every candidate must map c\'s child offsets (and end site, and translations that never change)\nonto its partner\'s: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates are the 24\nsigned permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where that leaves a choice\n(a bone\'s twist is invisible in its offsets):\n- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body\'s left-right axis as\n  seen in that frame (the principal axis of the hips\' and clavicles\' separations over the clip, which no yaw\n  or gesture changes) if it lies within 30 degrees of one; else, as in a joint that does not turn with the\n  body (a root above the pelvis), or a head held turned for a whole clip, it keeps its parent\'s;\n- a paired joint keeps its parent\'s M where that fits (a rig whose frames follow its symmetry: CMU\'s ASF,\n  S everywhere), else -I where that fits (a Maya-style rig mirrors the right side\'s axes as a whole);\n- anything else takes the candidate whose mirrored rotations come nearest, on average, to the partner\'s.\nA rig that is not axis-aligned gets the best fit of its offsets instead.\n"""\nimport itertools\n\nimport numpy as np\n\nfrom . import kinematics, quaternion\n\nWORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])\n# A captured skeleton\'s two sides differ by a few degrees (CMU 131\'s neck leans 7 degrees): within this the\n# axis-aligned convention is taken as the rig\'s, and the difference as capture asymmetry.\nALIGNED_COS = np.cos(np.radians(15.0))\nLATERAL_STEADINESS = 0.8  # share of the separations\' spread along the axis it takes to be one\nSTEADY_TRANSLATION = 1e-3  # relative spread under which a translation channel counts as a fixed offset\n\n\ndef _axis_aligned_reflections():\n    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror convention."""\n    out = []\n    for perm in itertools.permutations(range(3)):\n        for signs in itertools.product((1.0, -1.0), repeat=3):\n            m = np.zeros((3, 3))\n            m[list(perm), range(3)] = signs\n            if np.linalg.det(m) < 0:\n                out.append(m)\n    return out\n\n\nCANDIDATES = _axis_aligned_reflections()\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _unit(v):\n    v = np.asarray(v, dtype=np.float64)\n    norm = np.linalg.norm(v)\n    return v / norm if norm > 1e-9 else None\n\n\ndef _flips_one_axis(m):\n    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)\n\n\ndef _turning(a, b):\n    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when opposite)."""\n    axis = np.cross(a, b)\n    s, c = np.linalg.norm(axis), float(np.dot(a, b))\n    if s < 1e-12:\n        if c > 0:\n            return np.eye(3)\n        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0\n    axis = axis / np.linalg.norm(axis)\n    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])\n    return np.eye(3) + s * k + (1.0 - c) * (k @ k)\n\n\ndef _improper_fit(sources, targets):\n    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets (Kabsch)."""\n    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))\n    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt\n\n\ndef _fixed_offsets(offsets, translations, translated):\n    """Offsets, with those of translated joints whose translation never changes taken from it."""\n    offsets = np.array(offsets, dtype=np.float64)\n    for k, j in enumerate(translated):\n        t = np.asarray(translations, dtype=np.float64)[:, k]\n        mean = t.mean(axis=0)\n        offsets[j] = mean if np.abs(t - mean).max() <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0\n    return offsets\n\n\ndef _direction_pairs(j, children, offsets, end_sites, partner):\n    """(direction, partner\'s direction) of j\'s child offsets and end site, where both are non-zero."""\n    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]\n    if end_sites[j] is not None and end_sites[partner[j]] is not None:\n        pairs.append((end_sites[j], end_sites[partner[j]]))\n    units = [(_unit(a), _unit(b)) for a, b in pairs]\n    return [(a, b) for a, b in units if a is not None and b is not None]\n\n\ndef _lateral_axes(parents, positions, orientations, partner):\n    """Per joint, the body\'s left-right axis in the joint\'s own frame: the principal axis of the separations\n    of the pairs hung from one unpaired parent (hips, clavicles; or the first pair below them that is apart),\n    over all frames; zero where no axis holds (a root above the pelvis that does not turn with the body)."""\n    pairs = []\n    for c, m in enumerate(partner):\n        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:\n            while np.linalg.norm(positions[:, c] - positions[:, m], axis=-1).mean() < 1e-3:  # CMU\'s hip joints\n                below = [k for k in range(len(parents)) if parents[k] == c]\n                if not below:\n                    break\n                c, m = below[0], partner[below[0]]\n            pairs.append((c, m))\n    if not pairs:\n        return np.zeros((len(parents), 3))\n    separation = positions[:, [c for c, _ in pairs]] - positions[:, [m for _, m in pairs]]  # (F, P, 3)\n    separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)\n    local = quaternion.rotate(quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :])\n    values, vectors = np.linalg.eigh(np.einsum("fjpa,fjpb->jab", local, local))  # (J, 3, 3) scatter\n    steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)\n    turning = np.abs(orientations - orientations[:1]).max(axis=(0, 2)) > 1e-9  # a fixed frame is the world\'s\n    return vectors[:, :, -1] * (steady & turning)[:, None]\n\n\ndef _nearest_flip(candidates, axis):\n    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned for a\n    whole clip is no evidence of its frame)."""\n    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|\n    return best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None\n\n\ndef frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):\n    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3); mean_rotations:\n    (J, 3, 3) averages of the clip\'s parent-relative rotation matrices."""\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    out = np.empty((n_joints, 3, 3))\n    for j in range(n_joints):  # parents come before children\n        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one\'s\n            out[j] = out[partner[j]].T\n            continue\n        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]\n        pairs = _direction_pairs(j, children, offsets, end_sites, partner)\n        candidates = [m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)]\n        if partner[j] == j:\n            candidates = [m for m in candidates if _flips_one_axis(m)]\n        if not candidates:  # not axis-aligned: fit the offsets\n            sources = np.array([a for a, _ in pairs])\n            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:\n                out[j] = _improper_fit(sources, [b for _, b in pairs])\n                continue\n            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]\n        if len(candidates) == 1:\n            out[j] = candidates[0]\n        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:\n            out[j] = flip\n        elif any(np.allclose(m, above) for m in candidates):\n            out[j] = above\n        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):\n            out[j] = -np.eye(3)\n        else:\n            target = mean_rotations[partner[j]]\n            out[j] = min(candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target))\n    return out\n\n\ndef clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """M_j of every joint, found from a clip of the skeleton (see the module docstring)."""\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    return frame_reflections(parents, _fixed_offsets(offsets, translations, translated), end_sites, partner,\n                             _lateral_axes(parents, positions, orientations, partner),\n                             quaternion.to_matrix(rotations).mean(axis=0))\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    frames = clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated)\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = WORLD_REFLECTION if p < 0 else frames[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])\n    if not len(translated):\n        return out_rotations, translations\n    translations = np.asarray(translations, dtype=np.float64)\n    out_translations = np.empty_like(translations)\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]\n        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef conjugate(q):\n    """The inverse of unit quaternions: the same axis, the opposite angle."""\n    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = quaternion.conjugate(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.transitions': '"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and the\npart of it a chain can keep moving and steering in: the largest strongly connected component (as in\nmotion graphs) that holds turns both ways.\n\nOutside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a\ncomponent it cannot leave that never turns (in Bandai dataset 2, the runs: from a run\'s end only runs\npass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to the\nsteerable component keeps every chain where it can face its next goal.\n\nThe edge test is select_next_snippets\' level 0, computed for all pairs at once: the same search box\naround the end\'s features, the same per-joint ratio (position by the norm, rotation angle, velocities)\nwith the same float4 arithmetic, and the same rule against replaying the previous snippet\'s frames.\nNeeds scipy (the server: Debian\'s python3-scipy) for the box search and the components.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\nBOX_MARGIN = 1e-4  # match_box\'s margin: terminators store float4, features float8\n\n\nclass Terminators:\n    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19, 4)\n    as stored (float4), and features (n, 25)."""\n\n    def __init__(self, positions, rotations, velocities, angular_velocities, features):\n        n = len(features)\n        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)\n        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)\n        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)\n\n\ndef _norm(a, b, norm):\n    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens\n    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))\n\n\ndef _joint_terms(term, src, dst, plan, j):\n    """Joint j\'s continuity terms for pairs (end terminator src[k], begin terminator dst[k]): (difference,\n    threshold) for the rotation angle, the position (the plan\'s norm) and, with velocity terms, the\n    velocity and angular velocity."""\n    yield quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]), plan["angle_threshold"][j]\n    yield _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]), plan["position_threshold"][j]\n    if plan["velocity_terms"]:\n        yield _norm(term.velocities[src, j], term.velocities[dst, j], "l2"), plan["velocity_threshold"][j]\n        yield (_norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),\n               plan["angular_velocity_threshold"][j])\n\n\ndef _within(term, src, dst, plan):\n    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio is at\n    most 1. Joint by joint, the tightest first, so most pairs are dropped after one or two joints."""\n    keep = np.ones(len(src), dtype=bool)\n    order = sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j])\n    for j in order:\n        s, d = src[keep], dst[keep]\n        ok = np.ones(len(s), dtype=bool)\n        for difference, threshold in _joint_terms(term, s, d, plan, j):\n            ok &= difference <= threshold\n        keep[np.flatnonzero(keep)[~ok]] = False\n    return keep\n\n\ndef ratios(term, src, dst, plan):\n    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest over the\n    plan\'s joints and terms of difference / threshold (select_next_snippets\' continuity_ratio)."""\n    ratio = np.zeros(len(src))\n    for j in plan["joints"]:\n        for difference, threshold in _joint_terms(term, src, dst, plan, j):\n            ratio = np.maximum(ratio, difference / threshold)\n    return ratio\n\n\ndef edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):\n    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets given by\n    their begin and end terminator rows in `term`, their pose/rate group, clip (and version, mirror: one key)\n    and window. progress(done) is called after each chunk of sources."""\n    from scipy.spatial import cKDTree\n\n    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN\n    out_src, out_dst, out_ratio = [], [], []\n    done = 0\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        tree = cKDTree(term.features[begin[members]] / half)\n        for lo in range(0, len(members), chunk):\n            sources = members[lo:lo + chunk]\n            done += len(sources)\n            near = tree.query_ball_point(term.features[end[sources]] / half, r=1.0, p=np.inf)\n            counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))\n            if not counts.sum():\n                continue  # (progress is reported with the next chunk that has candidates)\n            s = np.repeat(sources, counts)\n            d = members[np.concatenate([np.asarray(c, dtype=np.int64) for c in near if len(c)])]\n            # No replay of the previous snippet\'s frames (its last frame, the seam, aside).\n            overlap = ((clip[s] == clip[d]) & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)\n                       & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1))\n            s, d = s[~overlap], d[~overlap]\n            keep = _within(term, end[s], begin[d], plan)\n            out_src.append(s[keep])\n            out_dst.append(d[keep])\n            out_ratio.append(ratios(term, end[s[keep]], begin[d[keep]], plan))\n            if progress:\n                progress(done)\n    if not out_src:\n        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)\n    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)\n\n\ndef steerable(n, src, dst, group, turn, min_turn):\n    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate group\n    among those (of more than one snippet) whose snippets include turns of at least min_turn radians each\n    way (`turn`: the heading change where each one leads). A chain in it can always move on, and can face\n    any goal. (The largest only, as in motion graphs: on Bandai dataset 2, adding the active walks\'\n    component to the slow walks\' made right-angle courses worse: README "Transition graphs".)"""\n    from scipy.sparse import coo_matrix\n    from scipy.sparse.csgraph import connected_components\n\n    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()\n    _, label = connected_components(graph, directed=True, connection="strong")\n    turn = np.asarray(turn, dtype=np.float64)\n    size = np.bincount(label, minlength=label.max() + 1)\n    left = np.zeros(len(size), dtype=bool)\n    right = np.zeros(len(size), dtype=bool)\n    np.logical_or.at(left, label, turn >= min_turn)\n    np.logical_or.at(right, label, turn <= -min_turn)\n    eligible = (size > 1) & left & right\n    keep = np.zeros(n, dtype=bool)\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        candidates = np.unique(label[members][eligible[label[members]]])\n        if len(candidates):\n            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True\n    return keep\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_7_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.7.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_7_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_7_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_7_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.7.0'] = kernel
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
kernel = GD.get('modb_kernel 0.7.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.cost_to_go': '"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of graph\nsnippets needs from that snippet\'s end until the pelvis is within the arrival radius of a goal, for goals\non a polar grid around that end (in its heading frame: x left, z forward).\n\nWhy: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind the\navatar when every successor of a straight walk goes straight, and circles a near goal. The cost-to-go\ncounts the turns the data can make after the candidate, however many snippets they take (as in\nnear-optimal controllers over motion graphs), so select_next_snippet\'s stored-transition level ranks by\n"seconds to the goal through this candidate" in one indexed lookup per candidate.\n\nComputed by value iteration (Bellman): V(s, g) = min over successors t of s of\nduration(t) + seam(s, t) + V(t, g seen from t\'s end), V = 0 within the arrival radius. seam(s, t) is the\ntransition\'s continuity ratio times the profile\'s continuity_weight / speed: the price the selection puts on\na rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals are read by\nbilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring\'s value plus the\nextra distance at the graph\'s median speed. The SQL reader is modb.cost_to_go, the same arithmetic.\n"""\nfrom dataclasses import asdict, dataclass\n\nimport numpy as np\n\nTOLERANCE = 0.01  # seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of convergence)\nMAX_ITERATIONS = 300\nMIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move\nEDGE_CHUNK = 4000  # sources per gather: bounds memory at about chunk x mean out-degree x grid size\n\n\n@dataclass(frozen=True)\nclass Grid:\n    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left) times\n    `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices the distance\n    beyond the outer ring. Values are stored angle-major: index angle * rings + ring."""\n    speed: float\n    angles: int = 24\n    rings: int = 11\n    inner_radius: float = 0.5\n    outer_radius: float = 12.0\n\n    def radii(self) -> np.ndarray:\n        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (np.arange(self.rings) / (self.rings - 1))\n\n    def points(self) -> tuple[np.ndarray, np.ndarray]:\n        """(x, z) of every grid point, in storage order."""\n        theta = np.arange(self.angles) * 2 * np.pi / self.angles\n        r = self.radii()\n        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()\n\n    def as_json(self) -> dict:\n        return asdict(self)\n\n\ndef interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):\n    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds added\n    beyond the outer ring. Goals within the inner radius get weights 0: reached."""\n    r = np.hypot(x, z)\n    ring = np.log(np.maximum(r, 1e-9) / grid.inner_radius) / np.log(grid.outer_radius / grid.inner_radius) * (grid.rings - 1)\n    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)\n    j0 = np.floor(ring).astype(np.int64)\n    wj = ring - j0\n    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)\n    a0 = np.floor(angle).astype(np.int64) % grid.angles\n    a1 = (a0 + 1) % grid.angles\n    wa = angle - np.floor(angle)\n    index = np.stack([a0 * grid.rings + j0, a0 * grid.rings + j0 + 1, a1 * grid.rings + j0, a1 * grid.rings + j0 + 1], -1)\n    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)\n    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed\n    reached = r <= grid.inner_radius\n    weight[reached] = 0\n    beyond[reached] = 0\n    return index, weight.astype(np.float32), beyond.astype(np.float32)\n\n\ndef seen_from_end(net_x, net_z, heading, x, z):\n    """Points (x, z) of a snippet\'s start frame seen from its end (modb.world_to_local): per snippet rows."""\n    dx = x[None, :] - np.asarray(net_x)[:, None]\n    dz = z[None, :] - np.asarray(net_z)[:, None]\n    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]\n    return dx * c - dz * s, dx * s + dz * c\n\n\ndef cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):\n    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.\n    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides the\n    duration of dst; a snippet without successors gets infinity."""\n    n = len(duration)\n    size = grid.angles * grid.rings\n    gx, gz = grid.points()\n    index, weight, beyond = interpolation(grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz))\n    index += (np.arange(n) * size)[:, None, None]  # into the flattened values\n    duration = np.asarray(duration, dtype=np.float32)[:, None]\n    order = np.argsort(src, kind="stable")\n    src, dst = np.asarray(src)[order], np.asarray(dst)[order]\n    seam = np.asarray(seam, dtype=np.float32)[order][:, None]\n    starts = np.r_[0, np.flatnonzero(np.diff(src)) + 1] if len(src) else np.zeros(0, dtype=np.int64)\n    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0\n    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.\n    values = np.tile(np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)).astype(np.float32)\n    values[:, ring0] = 0\n    change = np.inf\n    for iteration in range(1, MAX_ITERATIONS + 1):\n        through = duration + (values.ravel()[index] * weight).sum(-1) + beyond  # via each snippet as the next\n        new = np.full_like(values, np.inf)\n        for lo in range(0, len(starts), EDGE_CHUNK):\n            first = starts[lo:lo + EDGE_CHUNK]\n            stop = starts[lo + EDGE_CHUNK] if lo + EDGE_CHUNK < len(starts) else len(src)\n            new[src[first]] = np.minimum.reduceat(through[dst[first[0]:stop]] + seam[first[0]:stop], first - first[0], axis=0)\n        new[:, ring0] = 0\n        finite = np.isfinite(new)\n        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0\n        values = new\n        if progress:\n            progress(iteration, change)\n        if change < TOLERANCE:\n            break\n    return values, iteration, change\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The mirrored\njoint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how m(c)\'s frame sits\nagainst c\'s in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c (S R_root M_root at the\nroot), and a translated joint\'s translation becomes M_j t (S t at the root). Positions are exact whatever\nM is, as far as the captured skeleton is symmetric; rotations are what the same rig would report for the\nmirrored motion only with the rig\'s own M, and only then can mirrored snippets follow captured ones.\n\nFinding M_c. Every candidate must map c\'s child offsets (and end site, and translations that never change)\nonto its partner\'s: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates are the 24\nsigned permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where that leaves a choice\n(a bone\'s twist is invisible in its offsets):\n- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body\'s left-right axis as\n  seen in that frame (the principal axis of the hips\' and clavicles\' separations over the clip, which no yaw\n  or gesture changes) if it lies within 30 degrees of one; else, as in a joint that does not turn with the\n  body (a root above the pelvis), or a head held turned for a whole clip, it keeps its parent\'s;\n- a paired joint keeps its parent\'s M where that fits (a rig whose frames follow its symmetry: CMU\'s ASF,\n  S everywhere), else -I where that fits (a Maya-style rig mirrors the right side\'s axes as a whole);\n- anything else takes the candidate whose mirrored rotations come nearest, on average, to the partner\'s.\nA rig that is not axis-aligned gets the best fit of its offsets instead.\n"""\nimport itertools\n\nimport numpy as np\n\nfrom . import kinematics, quaternion\n\nWORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])\n# A captured skeleton\'s two sides differ by a few degrees (CMU 131\'s neck leans 7 degrees): within this the\n# axis-aligned convention is taken as the rig\'s, and the difference as capture asymmetry.\nALIGNED_COS = np.cos(np.radians(15.0))\nLATERAL_STEADINESS = 0.8  # share of the separations\' spread along the axis it takes to be one\nSTEADY_TRANSLATION = 1e-3  # relative spread under which a translation channel counts as a fixed offset\n\n\ndef _axis_aligned_reflections():\n    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror convention."""\n    out = []\n    for perm in itertools.permutations(range(3)):\n        for signs in itertools.product((1.0, -1.0), repeat=3):\n            m = np.zeros((3, 3))\n            m[list(perm), range(3)] = signs\n            if np.linalg.det(m) < 0:\n                out.append(m)\n    return out\n\n\nCANDIDATES = _axis_aligned_reflections()\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _unit(v):\n    v = np.asarray(v, dtype=np.float64)\n    norm = np.linalg.norm(v)\n    return v / norm if norm > 1e-9 else None\n\n\ndef _flips_one_axis(m):\n    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)\n\n\ndef _turning(a, b):\n    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when opposite)."""\n    axis = np.cross(a, b)\n    s, c = np.linalg.norm(axis), float(np.dot(a, b))\n    if s < 1e-12:\n        if c > 0:\n            return np.eye(3)\n        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0\n    axis = axis / np.linalg.norm(axis)\n    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])\n    return np.eye(3) + s * k + (1.0 - c) * (k @ k)\n\n\ndef _improper_fit(sources, targets):\n    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets (Kabsch)."""\n    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))\n    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt\n\n\ndef _fixed_offsets(offsets, translations, translated):\n    """Offsets, with those of translated joints whose translation never changes taken from it."""\n    offsets = np.array(offsets, dtype=np.float64)\n    for k, j in enumerate(translated):\n        t = np.asarray(translations, dtype=np.float64)[:, k]\n        mean = t.mean(axis=0)\n        offsets[j] = mean if np.abs(t - mean).max() <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0\n    return offsets\n\n\ndef _direction_pairs(j, children, offsets, end_sites, partner):\n    """(direction, partner\'s direction) of j\'s child offsets and end site, where both are non-zero."""\n    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]\n    if end_sites[j] is not None and end_sites[partner[j]] is not None:\n        pairs.append((end_sites[j], end_sites[partner[j]]))\n    units = [(_unit(a), _unit(b)) for a, b in pairs]\n    return [(a, b) for a, b in units if a is not None and b is not None]\n\n\ndef _lateral_axes(parents, positions, orientations, partner):\n    """Per joint, the body\'s left-right axis in the joint\'s own frame: the principal axis of the separations\n    of the pairs hung from one unpaired parent (hips, clavicles; or the first pair below them that is apart),\n    over all frames; zero where no axis holds (a root above the pelvis that does not turn with the body)."""\n    pairs = []\n    for c, m in enumerate(partner):\n        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:\n            while np.linalg.norm(positions[:, c] - positions[:, m], axis=-1).mean() < 1e-3:  # CMU\'s hip joints\n                below = [k for k in range(len(parents)) if parents[k] == c]\n                if not below:\n                    break\n                c, m = below[0], partner[below[0]]\n            pairs.append((c, m))\n    if not pairs:\n        return np.zeros((len(parents), 3))\n    separation = positions[:, [c for c, _ in pairs]] - positions[:, [m for _, m in pairs]]  # (F, P, 3)\n    separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)\n    local = quaternion.rotate(quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :])\n    values, vectors = np.linalg.eigh(np.einsum("fjpa,fjpb->jab", local, local))  # (J, 3, 3) scatter\n    steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)\n    turning = np.abs(orientations - orientations[:1]).max(axis=(0, 2)) > 1e-9  # a fixed frame is the world\'s\n    return vectors[:, :, -1] * (steady & turning)[:, None]\n\n\ndef _nearest_flip(candidates, axis):\n    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned for a\n    whole clip is no evidence of its frame)."""\n    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|\n    return best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None\n\n\ndef frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):\n    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3); mean_rotations:\n    (J, 3, 3) averages of the clip\'s parent-relative rotation matrices."""\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    out = np.empty((n_joints, 3, 3))\n    for j in range(n_joints):  # parents come before children\n        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one\'s\n            out[j] = out[partner[j]].T\n            continue\n        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]\n        pairs = _direction_pairs(j, children, offsets, end_sites, partner)\n        candidates = [m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)]\n        if partner[j] == j:\n            candidates = [m for m in candidates if _flips_one_axis(m)]\n        if not candidates:  # not axis-aligned: fit the offsets\n            sources = np.array([a for a, _ in pairs])\n            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:\n                out[j] = _improper_fit(sources, [b for _, b in pairs])\n                continue\n            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]\n        if len(candidates) == 1:\n            out[j] = candidates[0]\n        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:\n            out[j] = flip\n        elif any(np.allclose(m, above) for m in candidates):\n            out[j] = above\n        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):\n            out[j] = -np.eye(3)\n        else:\n            target = mean_rotations[partner[j]]\n            out[j] = min(candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target))\n    return out\n\n\ndef clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """M_j of every joint, found from a clip of the skeleton (see the module docstring)."""\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    return frame_reflections(parents, _fixed_offsets(offsets, translations, translated), end_sites, partner,\n                             _lateral_axes(parents, positions, orientations, partner),\n                             quaternion.to_matrix(rotations).mean(axis=0))\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    frames = clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated)\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = WORLD_REFLECTION if p < 0 else frames[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])\n    if not len(translated):\n        return out_rotations, translations\n    translations = np.asarray(translations, dtype=np.float64)\n    out_translations = np.empty_like(translations)\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]\n        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef conjugate(q):\n    """The inverse of unit quaternions: the same axis, the opposite angle."""\n    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = quaternion.conjugate(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.transitions': '"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and the\npart of it a chain can keep moving and steering in: the largest strongly connected component (as in\nmotion graphs) that holds turns both ways.\n\nOutside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a\ncomponent it cannot leave that never turns (in Bandai dataset 2, the runs: from a run\'s end only runs\npass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to the\nsteerable component keeps every chain where it can face its next goal.\n\nThe edge test is select_next_snippets\' level 0, computed for all pairs at once: the same search box\naround the end\'s features, the same per-joint ratio (position by the norm, rotation angle, velocities)\nwith the same float4 arithmetic, and the same rule against replaying the previous snippet\'s frames.\nNeeds scipy (the server: Debian\'s python3-scipy) for the box search and the components.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\nBOX_MARGIN = 1e-4  # match_box\'s margin: terminators store float4, features float8\n\n\nclass Terminators:\n    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19, 4)\n    as stored (float4), and features (n, 25)."""\n\n    def __init__(self, positions, rotations, velocities, angular_velocities, features):\n        n = len(features)\n        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)\n        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)\n        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)\n\n\ndef _norm(a, b, norm):\n    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens\n    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))\n\n\ndef _joint_terms(term, src, dst, plan, j):\n    """Joint j\'s continuity terms for pairs (end terminator src[k], begin terminator dst[k]): (difference,\n    threshold) for the rotation angle, the position (the plan\'s norm) and, with velocity terms, the\n    velocity and angular velocity."""\n    yield quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]), plan["angle_threshold"][j]\n    yield _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]), plan["position_threshold"][j]\n    if plan["velocity_terms"]:\n        yield _norm(term.velocities[src, j], term.velocities[dst, j], "l2"), plan["velocity_threshold"][j]\n        yield (_norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),\n               plan["angular_velocity_threshold"][j])\n\n\ndef _within(term, src, dst, plan):\n    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio is at\n    most 1. Joint by joint, the tightest first, so most pairs are dropped after one or two joints."""\n    keep = np.ones(len(src), dtype=bool)\n    order = sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j])\n    for j in order:\n        s, d = src[keep], dst[keep]\n        ok = np.ones(len(s), dtype=bool)\n        for difference, threshold in _joint_terms(term, s, d, plan, j):\n            ok &= difference <= threshold\n        keep[np.flatnonzero(keep)[~ok]] = False\n    return keep\n\n\ndef ratios(term, src, dst, plan):\n    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest over the\n    plan\'s joints and terms of difference / threshold (select_next_snippets\' continuity_ratio)."""\n    ratio = np.zeros(len(src))\n    for j in plan["joints"]:\n        for difference, threshold in _joint_terms(term, src, dst, plan, j):\n            ratio = np.maximum(ratio, difference / threshold)\n    return ratio\n\n\ndef edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):\n    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets given by\n    their begin and end terminator rows in `term`, their pose/rate group, clip (and version, mirror: one key)\n    and window. progress(done) is called after each chunk of sources."""\n    from scipy.spatial import cKDTree\n\n    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN\n    out_src, out_dst, out_ratio = [], [], []\n    done = 0\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        tree = cKDTree(term.features[begin[members]] / half)\n        for lo in range(0, len(members), chunk):\n            sources = members[lo:lo + chunk]\n            done += len(sources)\n            near = tree.query_ball_point(term.features[end[sources]] / half, r=1.0, p=np.inf)\n            counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))\n            if not counts.sum():\n                continue  # (progress is reported with the next chunk that has candidates)\n            s = np.repeat(sources, counts)\n            d = members[np.concatenate([np.asarray(c, dtype=np.int64) for c in near if len(c)])]\n            # No replay of the previous snippet\'s frames (its last frame, the seam, aside).\n            overlap = ((clip[s] == clip[d]) & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)\n                       & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1))\n            s, d = s[~overlap], d[~overlap]\n            keep = _within(term, end[s], begin[d], plan)\n            out_src.append(s[keep])\n            out_dst.append(d[keep])\n            out_ratio.append(ratios(term, end[s[keep]], begin[d[keep]], plan))\n            if progress:\n                progress(done)\n    if not out_src:\n        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)\n    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)\n\n\ndef steerable(n, src, dst, group, turn, min_turn):\n    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate group\n    among those (of more than one snippet) whose snippets include turns of at least min_turn radians each\n    way (`turn`: the heading change where each one leads). A chain in it can always move on, and can face\n    any goal. (The largest only, as in motion graphs: on Bandai dataset 2, adding the active walks\'\n    component to the slow walks\' made right-angle courses worse: README "Transition graphs".)"""\n    from scipy.sparse import coo_matrix\n    from scipy.sparse.csgraph import connected_components\n\n    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()\n    _, label = connected_components(graph, directed=True, connection="strong")\n    turn = np.asarray(turn, dtype=np.float64)\n    size = np.bincount(label, minlength=label.max() + 1)\n    left = np.zeros(len(size), dtype=bool)\n    right = np.zeros(len(size), dtype=bool)\n    np.logical_or.at(left, label, turn >= min_turn)\n    np.logical_or.at(right, label, turn <= -min_turn)\n    eligible = (size > 1) & left & right\n    keep = np.zeros(n, dtype=bool)\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        candidates = np.unique(label[members][eligible[label[members]]])\n        if len(candidates):\n            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True\n    return keep\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_7_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.7.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_7_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_7_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_7_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.7.0'] = kernel
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

-- 70_snippets.sql
-- Snippets (~0.5 s windows of real capture), the terminators at their ends, and where they came from.
-- The frames themselves stay in modb.clip_versions: a snippet is a window onto them, never a copy.

CREATE FUNCTION modb.skeleton_pose_key(hierarchy jsonb)
RETURNS text
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- End Sites move no joint: snippets of skeletons that differ only there may follow each other.
    SELECT modb.skeleton_identity(jsonb_set(hierarchy, '{joints}', (
        SELECT jsonb_agg(j - 'end_site' ORDER BY n)
          FROM jsonb_array_elements(hierarchy->'joints') WITH ORDINALITY AS t(j, n))));
END;
COMMENT ON FUNCTION modb.skeleton_pose_key(jsonb) IS
    'Identity of the poses a skeleton can take (skeleton_identity without End Sites): snippets chain only within one';

CREATE TABLE modb.snippet_sources (
    clip_id       bigint NOT NULL,
    version       int NOT NULL,
    mirrored      boolean NOT NULL,
    window_frames int NOT NULL CHECK (window_frames > 1),
    stride_frames int NOT NULL CHECK (stride_frames > 0),
    built_at      timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (clip_id, version, mirrored),
    FOREIGN KEY (clip_id, version) REFERENCES modb.clip_versions (clip_id, version) ON DELETE CASCADE
);
COMMENT ON TABLE modb.snippet_sources IS
    'Clip versions (as captured or mirrored) cut into snippets, with the window and stride used (frames)';

CREATE TABLE modb.terminators (
    id                 bigserial PRIMARY KEY,
    clip_id            bigint NOT NULL,
    version            int NOT NULL,
    mirrored           boolean NOT NULL,
    frame              int NOT NULL CHECK (frame >= 0),
    heading            float8 NOT NULL,
    pelvis_height      real NOT NULL,
    positions          real[] NOT NULL CHECK (array_length(positions, 1) = 57),
    rotations          real[] NOT NULL CHECK (array_length(rotations, 1) = 76),
    velocities         real[] NOT NULL CHECK (array_length(velocities, 1) = 57),
    angular_velocities real[] NOT NULL CHECK (array_length(angular_velocities, 1) = 57),
    configuration      real[] NOT NULL,
    features           cube NOT NULL CHECK (cube_dim(features) = 25),
    UNIQUE (clip_id, version, mirrored, frame),
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE
);
COMMENT ON TABLE modb.terminators IS
    'MotionTerminator: the configuration at a frame that begins or ends a snippet, in that frame''s local heading frame';
COMMENT ON COLUMN modb.terminators.heading IS 'World heading (radians about +Y, 0 = facing +Z) of the frame, smoothed over 0.5 s';
COMMENT ON COLUMN modb.terminators.positions IS
    'Standard joints (modb.standard_joints() order) x (x, y, z): metres, local heading frame, origin at the pelvis on the ground';
COMMENT ON COLUMN modb.terminators.rotations IS
    'Standard joints x (w, x, y, z): the pelvis in the heading frame, every other joint relative to its parent';
COMMENT ON COLUMN modb.terminators.velocities IS 'Standard joints x (x, y, z) m/s, local heading frame';
COMMENT ON COLUMN modb.terminators.angular_velocities IS
    'Standard joints x (x, y, z) rad/s: the pelvis in the heading frame, other joints in their own frame';
COMMENT ON COLUMN modb.terminators.configuration IS
    'real[n_joints][4]: every joint''s unit quaternion (skeleton order); the pelvis in the heading frame';
COMMENT ON COLUMN modb.terminators.features IS
    'The indexed feature vector, physical units: modb.feature_names() lists its 25 dimensions';

CREATE TABLE modb.snippets (
    id               bigserial PRIMARY KEY,
    clip_id          bigint NOT NULL,
    version          int NOT NULL,
    mirrored         boolean NOT NULL,
    first_frame      int NOT NULL CHECK (first_frame >= 0),
    n_frames         int NOT NULL CHECK (n_frames > 1),
    collection_id    bigint NOT NULL,
    pose_key         text NOT NULL,
    fps              float8 NOT NULL,
    begin_terminator bigint NOT NULL REFERENCES modb.terminators (id) ON DELETE CASCADE,
    end_terminator   bigint NOT NULL REFERENCES modb.terminators (id) ON DELETE CASCADE,
    begin_features   cube NOT NULL,
    net_translation  float8[] NOT NULL CHECK (array_length(net_translation, 1) = 3),
    net_heading      float8 NOT NULL,
    net_rotation     float8[] NOT NULL CHECK (array_length(net_rotation, 1) = 4),
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE,
    future_translation float8[] CHECK (array_length(future_translation, 1) = 3),
    future_heading     float8
);
COMMENT ON TABLE modb.snippets IS
    'SnippetDescriptor: frames first_frame .. first_frame + n_frames - 1 of a clip version; played after another snippet, its first frame stands in for that one''s last';
COMMENT ON COLUMN modb.snippets.begin_features IS 'Copy of the begin terminator''s features, so the GiST index serves the selection alone';
COMMENT ON COLUMN modb.snippets.net_translation IS 'Pelvis travel (x left, y up, z forward; metres) in the heading frame of the first frame';
COMMENT ON COLUMN modb.snippets.net_heading IS 'Heading change over the snippet (radians, counter-clockwise seen from above)';
COMMENT ON COLUMN modb.snippets.net_rotation IS 'The heading change as a unit quaternion (w, x, y, z) about +Y';
COMMENT ON COLUMN modb.snippets.future_translation IS
    'Where playing on leads: pelvis travel over this snippet and up to two play-on snippets of its clip (1.5 s for 0.5 s windows), in the heading frame of its first frame; the objective of select_next_snippet';
COMMENT ON COLUMN modb.snippets.future_heading IS 'The heading change over the same frames as future_translation (radians)';

CREATE INDEX snippets_begin_features_idx ON modb.snippets USING gist (begin_features);
CREATE INDEX snippets_clip_idx ON modb.snippets (clip_id, version, mirrored, first_frame);
CREATE INDEX snippets_pose_key_idx ON modb.snippets (pose_key, fps);
-- For the foreign keys: deleting a clip version's terminators must not scan every snippet per row.
CREATE INDEX snippets_begin_terminator_idx ON modb.snippets (begin_terminator);
CREATE INDEX snippets_end_terminator_idx ON modb.snippets (end_terminator);

SELECT pg_catalog.pg_extension_config_dump('modb.snippet_sources', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators', '');
SELECT pg_catalog.pg_extension_config_dump('modb.terminators_id_seq', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets', '');
SELECT pg_catalog.pg_extension_config_dump('modb.snippets_id_seq', '');

GRANT SELECT ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_reader;
GRANT INSERT, DELETE ON modb.snippet_sources, modb.terminators, modb.snippets TO modb_loader;
GRANT USAGE ON modb.terminators_id_seq, modb.snippets_id_seq TO modb_loader;

-- 71_futures.sql
-- Where a snippet leads: itself and up to two play-on snippets (each starting on the previous one's last
-- frame, in the same clip version and mirror image), composed from their net motions. The objective of
-- select_next_snippet measures this, so that a choice that leads into a turn is seen as turning: a
-- snippet's own 0.5 s says little about where the clip goes (a turn clip's lead-in walks straight).

CREATE FUNCTION modb.fill_futures()
RETURNS bigint
LANGUAGE sql VOLATILE PARALLEL UNSAFE
BEGIN ATOMIC
    WITH chain AS (
        SELECT s.id, s.net_translation AS t0, s.net_heading AS h0,
               a.net_translation AS t1, coalesce(a.net_heading, 0) AS h1,
               b.net_translation AS t2, coalesce(b.net_heading, 0) AS h2
          FROM modb.snippets s
          LEFT JOIN modb.snippets a ON a.clip_id = s.clip_id AND a.version = s.version AND a.mirrored = s.mirrored
                                   AND a.first_frame = s.first_frame + s.n_frames - 1
          LEFT JOIN modb.snippets b ON b.clip_id = a.clip_id AND b.version = a.version AND b.mirrored = a.mirrored
                                   AND b.first_frame = a.first_frame + a.n_frames - 1
         WHERE s.future_translation IS NULL
    ), updated AS (
        UPDATE modb.snippets s
           SET future_translation = ARRAY[
                   c.t0[1] + coalesce(c.t1[1] * cos(c.h0) + c.t1[3] * sin(c.h0), 0)
                           + coalesce(c.t2[1] * cos(c.h0 + c.h1) + c.t2[3] * sin(c.h0 + c.h1), 0),
                   c.t0[2] + coalesce(c.t1[2], 0) + coalesce(c.t2[2], 0),
                   c.t0[3] + coalesce(c.t1[3] * cos(c.h0) - c.t1[1] * sin(c.h0), 0)
                           + coalesce(c.t2[3] * cos(c.h0 + c.h1) - c.t2[1] * sin(c.h0 + c.h1), 0)],
               future_heading = atan2(sin(c.h0 + c.h1 + c.h2), cos(c.h0 + c.h1 + c.h2))
          FROM chain c
         WHERE c.id = s.id
        RETURNING 1)
    SELECT count(*) FROM updated;
END;
COMMENT ON FUNCTION modb.fill_futures() IS
    'Fills future_translation and future_heading of the snippets that lack them (build_snippets calls it); returns how many';
REVOKE EXECUTE ON FUNCTION modb.fill_futures() FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.fill_futures() TO modb_loader;

-- 72_matching.sql
-- How two terminators are compared: the quaternion-angle operator, configuration-level distances,
-- match profiles with per-session knobs, and the per-dimension search box.

CREATE FUNCTION modb.standard_joints()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN ARRAY['pelvis', 'spine', 'chest', 'neck', 'head', 'left_hip', 'left_knee', 'left_ankle', 'left_toe', 'left_shoulder', 'left_elbow', 'left_wrist', 'right_hip', 'right_knee', 'right_ankle', 'right_toe', 'right_shoulder', 'right_elbow', 'right_wrist'];  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.standard_joints() IS
    'The standard joints in the order terminator arrays use (index 0 = pelvis); a joint map maps them onto a skeleton';

CREATE FUNCTION modb.feature_names()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN ARRAY['pelvis.y', 'head.x', 'head.y', 'head.z', 'left_wrist.x', 'left_wrist.y', 'left_wrist.z', 'right_wrist.x', 'right_wrist.y', 'right_wrist.z', 'left_ankle.x', 'left_ankle.y', 'left_ankle.z', 'right_ankle.x', 'right_ankle.y', 'right_ankle.z', 'pelvis.vx', 'pelvis.vy', 'pelvis.vz', 'left_ankle.vx', 'left_ankle.vy', 'left_ankle.vz', 'right_ankle.vx', 'right_ankle.vy', 'right_ankle.vz'];  -- written by build_sql.py from modb_kernel/joints.py
COMMENT ON FUNCTION modb.feature_names() IS 'The 25 dimensions of the indexed feature cube, in order (metres, m/s)';

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

CREATE TABLE modb.match_profiles (
    name     text PRIMARY KEY,
    settings jsonb NOT NULL CHECK (jsonb_typeof(settings) = 'object'),
    comment  text,
    shipped  boolean NOT NULL DEFAULT false
);
COMMENT ON TABLE modb.match_profiles IS
    'Continuity thresholds for select_next_snippet, by name; any setting can be overridden per session with SET modb.<knob>';

-- The shipped profiles: 73_profiles.sql (also run by upgrades, so they follow the release).

GRANT SELECT ON modb.match_profiles TO modb_reader;
GRANT INSERT, UPDATE, DELETE ON modb.match_profiles TO modb_loader;

-- The shipped profiles come with every install (and upgrade); pg_dump keeps the ones users add.
SELECT pg_catalog.pg_extension_config_dump('modb.match_profiles', 'WHERE NOT shipped');
COMMENT ON COLUMN modb.match_profiles.shipped IS
    'Installed with the extension (and replaced by its upgrades): add your own profile rather than editing these';

CREATE TYPE modb.match_plan AS (
    joints                     int[],
    position_threshold         float8[],
    angle_threshold            float8[],
    velocity_threshold         float8[],
    angular_velocity_threshold float8[],
    norm                       text,
    velocity_terms             boolean,
    heading_weight             float8,
    box_half_width             float8[],
    continuity_weight          float8,
    lookahead_distance         float8,
    graph_id                   bigint,
    graph_lookahead            boolean,
    graph_cost_to_go           boolean
);
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, the objective''s weights, the transition graph (modb.graphs id) candidates must belong to, if any, whether the objective looks one snippet further through it, and whether it ranks by the graph''s cost-to-go';

CREATE FUNCTION modb.session_settings()
RETURNS text[]
LANGUAGE c STABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_session_settings';
COMMENT ON FUNCTION modb.session_settings() IS
    'Names of this session''s modb.* settings that have a value (pg_settings does not list them: they are placeholders)';

CREATE FUNCTION modb._thresholds(spec jsonb, joints text[], included text[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
BEGIN ATOMIC
    SELECT array_agg(CASE WHEN j <> ALL (included) THEN 'Infinity'::float8
                          WHEN jsonb_typeof(spec) = 'number' THEN spec::text::float8
                          ELSE coalesce((spec->>j)::float8, (spec->>'default')::float8) END ORDER BY n)
      FROM unnest(joints) WITH ORDINALITY AS t(j, n);
END;
COMMENT ON FUNCTION modb._thresholds(jsonb, text[], text[]) IS
    'Internal: a threshold per joint from a number or {"default": x, "<joint>": y}; Infinity for joints not included';

-- modb.continuity_ratio: 72_matching_continuity.sql

CREATE FUNCTION modb.match_box(features cube, plan modb.match_plan, scale float8)
RETURNS cube
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    -- + 1e-4: terminators store float4 and features float8; the margin keeps every candidate that passes
    -- the exact check inside the box, so a row's level depends on its ratio alone.
    SELECT cube(array_agg(cube_ll_coord(features, i) - scale * (plan).box_half_width[i] - 1e-4 ORDER BY i),
                array_agg(cube_ll_coord(features, i) + scale * (plan).box_half_width[i] + 1e-4 ORDER BY i))
      FROM generate_series(1, cube_dim(features)) AS i;
END;
COMMENT ON FUNCTION modb.match_box(cube, modb.match_plan, float8) IS
    'The per-dimension search box around a feature point: each feature +- scale x its joint''s threshold';

CREATE FUNCTION modb.target_cost(net_translation float8[], net_heading float8, target float8[], heading_weight float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
RETURN CASE WHEN array_length(target, 1) = 3
            THEN sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[2] - target[2]) ^ 2 + (net_translation[3] - target[3]) ^ 2)
            ELSE sqrt((net_translation[1] - target[1]) ^ 2 + (net_translation[3] - target[2]) ^ 2) END
       + heading_weight * abs(atan2(sin(net_heading - atan2(target[1], target[array_length(target, 1)])),
                                    cos(net_heading - atan2(target[1], target[array_length(target, 1)]))));
COMMENT ON FUNCTION modb.target_cost(float8[], float8, float8[], float8) IS
    'Distance (m) from a snippet''s net translation to the target {x, z} or {x, y, z}, plus heading_weight x |heading change - direction of the target| (radians)';

CREATE FUNCTION modb.collection_subtree(path text)
RETURNS bigint[]
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    WITH RECURSIVE down(id, depth) AS (
        SELECT id, 0 FROM modb.collections WHERE id = modb.find_collection(path)
        UNION ALL
        SELECT c.id, down.depth + 1 FROM modb.collections c JOIN down ON c.parent_id = down.id WHERE down.depth < 1000
    )
    SELECT coalesce(array_agg(id), '{}') FROM down;
END;
COMMENT ON FUNCTION modb.collection_subtree(text) IS 'Ids of the collection at path "a/b" and of every collection below it';

CREATE FUNCTION modb.check_request(prev_snippet bigint, target float8[], k int, collection text)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    IF target IS NULL OR array_length(target, 1) NOT IN (2, 3) OR array_ndims(target) <> 1
       OR EXISTS (SELECT FROM unnest(target) v WHERE v IS NULL OR v = 'NaN' OR v IN ('Infinity', '-Infinity')) THEN
        RAISE EXCEPTION 'target must be {x, z} or {x, y, z} in metres, got %', coalesce(target::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF k IS NULL OR k < 1 THEN
        RAISE EXCEPTION 'k must be at least 1, got %', coalesce(k::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF prev_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = prev_snippet) THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'prev_snippet is a modb.snippets id, or NULL to start';
    END IF;
    IF collection IS NOT NULL AND modb.find_collection(collection) IS NULL THEN
        RAISE EXCEPTION 'no collection "%"', collection USING ERRCODE = 'invalid_parameter_value';
    END IF;
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_request(bigint, float8[], int, text) IS
    'Raises a clear error for a select_next_snippet request that cannot be answered (bad target or k, unknown snippet or collection)';

-- 72_matching_continuity.sql
-- The continuity ratio of a seam (select_next_snippet's exact check). In C since 0.7.0: the same arithmetic
-- as the inlined SQL expression before it (src/continuity.c), ~100x faster a candidate. CREATE OR REPLACE:
-- upgrades include this file.

CREATE OR REPLACE FUNCTION modb.continuity_ratio_native(a modb.terminators, b modb.terminators, plan modb.match_plan)
RETURNS float8
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_continuity_ratio';
COMMENT ON FUNCTION modb.continuity_ratio_native(modb.terminators, modb.terminators, modb.match_plan) IS
    'Internal: modb.continuity_ratio''s arithmetic in C';

CREATE OR REPLACE FUNCTION modb.continuity_ratio(a modb.terminators, b modb.terminators, plan modb.match_plan)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- A SQL wrapper, inlined into the selection's plan, around the C function.
RETURN modb.continuity_ratio_native(a, b, plan);
COMMENT ON FUNCTION modb.continuity_ratio(modb.terminators, modb.terminators, modb.match_plan) IS
    'max over included joints of difference/threshold (position by the profile''s norm, quaternion angle, velocities): <= 1 within thresholds';

-- 72_plan.sql
-- Resolving a match profile (with a session's SET modb.<knob> overrides) into a modb.match_plan.
-- CREATE OR REPLACE: upgrades include this file when the plan changes.

CREATE OR REPLACE FUNCTION modb.match_knobs()
RETURNS text[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN ARRAY['joints', 'norm', 'position_threshold', 'angle_threshold', 'velocity_threshold',
             'angular_velocity_threshold', 'velocity_terms', 'heading_weight', 'continuity_weight', 'lookahead_distance',
             'graph', 'graph_lookahead', 'graph_cost_to_go'];
COMMENT ON FUNCTION modb.match_knobs() IS 'Settings a session may override with SET modb.<knob> = ...';

CREATE OR REPLACE FUNCTION modb.match_plan(profile text)
RETURNS modb.match_plan
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    settings jsonb;
    knob text;
    value text;
    unknown text;
    plan modb.match_plan;
    names text[] := modb.standard_joints();
    features text[] := modb.feature_names();
    joint_names text[];
    position_by_joint float8[];
    velocity_by_joint float8[];
    included boolean[];
    feature text;
    joint text;
    s int;
BEGIN
    SELECT p.settings INTO settings FROM modb.match_profiles p WHERE p.name = coalesce(profile, 'default');
    IF NOT FOUND THEN
        RAISE EXCEPTION 'unknown match profile "%"', profile
            USING HINT = 'profiles: ' || (SELECT string_agg(name, ', ' ORDER BY name) FROM modb.match_profiles);
    END IF;
    SELECT string_agg(name, ', ') INTO unknown
      FROM unnest(modb.session_settings()) AS name WHERE substr(name, 6) <> ALL (modb.match_knobs());
    IF unknown IS NOT NULL THEN
        RAISE EXCEPTION 'unknown modb setting: %', unknown
            USING HINT = 'knobs are modb.' || array_to_string(modb.match_knobs(), ', modb.') || '; RESET the unknown one';
    END IF;
    FOREACH knob IN ARRAY modb.match_knobs() LOOP
        value := nullif(current_setting('modb.' || knob, true), '');
        CONTINUE WHEN value IS NULL;
        settings := settings || jsonb_build_object(knob, CASE
            WHEN knob = 'joints' THEN to_jsonb(string_to_array(replace(value, ' ', ''), ','))
            WHEN knob = 'norm' THEN to_jsonb(lower(value))
            WHEN knob = 'graph' THEN to_jsonb(value)
            WHEN knob IN ('velocity_terms', 'graph_lookahead', 'graph_cost_to_go') THEN to_jsonb(value::boolean)
            WHEN knob LIKE '%threshold' THEN jsonb_build_object('default', value::float8)  -- one value for every joint
            ELSE to_jsonb(value::float8) END);
    END LOOP;
    joint_names := ARRAY(SELECT jsonb_array_elements_text(settings->'joints'));
    IF joint_names = '{}' OR EXISTS (SELECT FROM unnest(joint_names) j WHERE j <> ALL (names)) THEN
        RAISE EXCEPTION 'profile "%": joints % must be standard joints', profile, joint_names
            USING HINT = 'standard joints: ' || array_to_string(names, ', ');
    END IF;
    IF EXISTS (SELECT FROM jsonb_each(settings) AS e(k, v)
                WHERE k LIKE '%threshold'
                  AND EXISTS (SELECT FROM jsonb_path_query(v, 'strict $.** ? (@.type() == "number")') AS x(n)
                              WHERE NOT (x.n::text::float8 > 0))) THEN
        RAISE EXCEPTION 'profile "%": thresholds must be positive', profile
            USING HINT = 'check SET modb.*_threshold and the profile''s settings';
    END IF;
    IF coalesce((settings->>'heading_weight')::float8, 0) < 0 THEN
        RAISE EXCEPTION 'profile "%": heading_weight must not be negative', profile;
    END IF;
    IF coalesce((settings->>'continuity_weight')::float8, 0) < 0 THEN
        RAISE EXCEPTION 'profile "%": continuity_weight must not be negative', profile;
    END IF;
    IF NOT coalesce((settings->>'lookahead_distance')::float8, 1) > 0 THEN
        RAISE EXCEPTION 'profile "%": lookahead_distance must be positive (or absent: score against the goal itself)', profile;
    END IF;
    plan.norm := coalesce(settings->>'norm', 'l2');
    IF plan.norm NOT IN ('l1', 'l2') THEN
        RAISE EXCEPTION 'norm must be l1 or l2, not "%"', plan.norm;
    END IF;
    plan.velocity_terms := coalesce((settings->>'velocity_terms')::boolean, true);
    plan.heading_weight := coalesce((settings->>'heading_weight')::float8, 0);
    plan.continuity_weight := coalesce((settings->>'continuity_weight')::float8, 0);
    plan.lookahead_distance := (settings->>'lookahead_distance')::float8;
    plan.graph_lookahead := coalesce((settings->>'graph_lookahead')::boolean, false);
    plan.graph_cost_to_go := coalesce((settings->>'graph_cost_to_go')::boolean, true);
    IF settings ? 'graph' THEN
        SELECT g.id INTO plan.graph_id FROM modb.graphs g WHERE g.name = settings->>'graph' AND g.kind = 'transitions';
        IF NOT FOUND THEN
            RAISE EXCEPTION 'no transition graph "%"', settings->>'graph'
                USING HINT = 'build it with modb.build_transition_graph(''' || (settings->>'graph') || ''') or `modb graph build`';
        END IF;
    END IF;
    plan.joints := ARRAY(SELECT array_position(names, j) - 1 FROM unnest(joint_names) WITH ORDINALITY t(j, n) ORDER BY n);
    plan.position_threshold := modb._thresholds(settings->'position_threshold', names, joint_names);
    plan.angle_threshold := modb._thresholds(settings->'angle_threshold', names, joint_names);
    plan.velocity_threshold := modb._thresholds(settings->'velocity_threshold', names, joint_names);
    plan.angular_velocity_threshold := modb._thresholds(settings->'angular_velocity_threshold', names, joint_names);
    position_by_joint := plan.position_threshold;
    velocity_by_joint := plan.velocity_threshold;
    -- Box half-widths: a feature of an included joint gets that joint's threshold (an L1 or L2 ball
    -- lies inside the box of its radius, so the box loses no candidate); the others are unbounded.
    plan.box_half_width := '{}';
    FOREACH feature IN ARRAY features LOOP
        joint := split_part(feature, '.', 1);
        s := array_position(names, joint);
        plan.box_half_width := plan.box_half_width || CASE
            WHEN joint <> ALL (joint_names) THEN 1e6::float8  -- unbounded, without infinities in the cube
            WHEN split_part(feature, '.', 2) LIKE 'v_' THEN
                CASE WHEN plan.velocity_terms THEN velocity_by_joint[s] ELSE 1e6::float8 END
            ELSE position_by_joint[s] END;
    END LOOP;
    RETURN plan;
END
$$;
COMMENT ON FUNCTION modb.match_plan(text) IS
    'Resolves a match profile with this session''s SET modb.<knob> overrides; an unknown profile or knob is an error';

CREATE OR REPLACE FUNCTION modb.aim_point(target float8[], lookahead_distance float8)
RETURNS float8[]
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- Scales the ground part ({x, z}, or x and z of {x, y, z}) down to lookahead_distance; NULL: the target.
RETURN (SELECT CASE WHEN lookahead_distance IS NULL OR lookahead_distance >= ground THEN target
                    WHEN array_length(target, 1) = 3
                    THEN ARRAY[target[1] * lookahead_distance / ground, target[2], target[3] * lookahead_distance / ground]
                    ELSE ARRAY[target[1] * lookahead_distance / ground, target[2] * lookahead_distance / ground] END
          FROM (SELECT sqrt(target[1] ^ 2 + target[array_length(target, 1)] ^ 2) AS ground) g);
COMMENT ON FUNCTION modb.aim_point(float8[], float8) IS
    'The point the objective scores against: the target, or the point lookahead_distance metres (on the ground) along the way to it when it is farther';

CREATE OR REPLACE FUNCTION modb.approach_cost(net_translation float8[], future_translation float8[],
                                              future_heading float8, aim float8[], heading_weight float8)
RETURNS float8
LANGUAGE sql IMMUTABLE CALLED ON NULL INPUT PARALLEL SAFE
-- The nearer of the two points on the candidate's way: where it ends, and where playing on leads. The end
-- counts so that a near goal is reached: scored by the 1.5 s point alone, a snippet stopping on the goal
-- loses to one whose play-on curves back to it, and the avatar circles the goal (README "Synthesis quality").
RETURN least(modb.target_cost(net_translation, future_heading, aim, heading_weight),
             modb.target_cost(future_translation, future_heading, aim, heading_weight));
COMMENT ON FUNCTION modb.approach_cost(float8[], float8[], float8, float8[], float8) IS
    'The objective of select_next_snippet: distance (m) from the aim point to the nearer of the snippet''s end and where playing on leads, plus heading_weight x |heading change where playing on leads - direction of the aim| (radians)';

-- 73_profiles.sql
-- The shipped match profiles. An upsert, so that upgrade scripts include this file and shipped rows follow
-- the release (rows a user added are never touched; shipped rows are not in pg_dump's output).
--
-- default (0.3.0): each joint's angle threshold is its 99th percentile change between consecutive
-- frames of real walking and running (Bandai dataset 2 locomotion, 30 fps: neck 2.1, spine 2.7, knees 21
-- degrees per frame), so that a seam looks like a natural step (README "Synthesis quality"); a heading
-- term of 1 m per radian turns the avatar toward its goal, and continuity_weight 0.6 m per unit of
-- continuity ratio (0.3 before 0.6.0: with a graph's cost-to-go, which prices seams by it too, 0.6 gave
-- smoother seams on six seeded courses, the 10-minute one and the right-angle one, with every counted goal
-- within 2x; BENCHMARKS.md "Cost-to-go") keeps the
-- smoother candidate unless another leads clearly better; lookahead_distance
-- 2.5 m (about where a walk leads in the 1.5 s the objective sees) scores a far goal as a point that far
-- along the way, so that it does not favour runs, which in this data never turn (README "Synthesis
-- quality"). strict: half the thresholds.

INSERT INTO modb.match_profiles AS p (name, settings, comment, shipped) VALUES
('default', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
              "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
              "right_shoulder", "right_elbow", "right_wrist"],
              "norm": "l2", "position_threshold": {"default": 0.12, "left_wrist": 0.2, "right_wrist": 0.2,
              "left_elbow": 0.16, "right_elbow": 0.16},
              "angle_threshold": {"default": 0.3, "pelvis": 0.11, "spine": 0.047, "chest": 0.093, "neck": 0.037,
              "head": 0.066, "left_hip": 0.23, "right_hip": 0.23, "left_knee": 0.37, "right_knee": 0.37,
              "left_ankle": 0.34, "right_ankle": 0.34, "left_toe": 0.36, "right_toe": 0.36, "left_shoulder": 0.29,
              "right_shoulder": 0.29, "left_elbow": 0.34, "right_elbow": 0.34, "left_wrist": 0.093, "right_wrist": 0.093},
              "velocity_threshold": {"default": 0.6, "left_wrist": 1.0, "right_wrist": 1.0, "left_elbow": 0.8,
              "right_elbow": 0.8},
              "angular_velocity_threshold": {"default": 4.0}, "velocity_terms": true, "heading_weight": 1.0,
              "continuity_weight": 0.6, "lookahead_distance": 2.5}',
 'Whole body: feet, hands and head within centimetres, each joint within its natural frame-to-frame change at 30 fps, velocities matched; the smoother candidate wins unless another leads clearly better toward the goal', true),
('strict', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
             "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
             "right_shoulder", "right_elbow", "right_wrist"],
             "norm": "l2", "position_threshold": {"default": 0.06},
             "angle_threshold": {"default": 0.15, "pelvis": 0.055, "spine": 0.0235, "chest": 0.0465, "neck": 0.0185,
             "head": 0.033, "left_hip": 0.115, "right_hip": 0.115, "left_knee": 0.185, "right_knee": 0.185,
             "left_ankle": 0.17, "right_ankle": 0.17, "left_toe": 0.18, "right_toe": 0.18, "left_shoulder": 0.145,
             "right_shoulder": 0.145, "left_elbow": 0.17, "right_elbow": 0.17, "left_wrist": 0.0465, "right_wrist": 0.0465},
             "velocity_threshold": {"default": 0.3}, "angular_velocity_threshold": {"default": 2.0},
             "velocity_terms": true, "heading_weight": 1.0, "continuity_weight": 0.3,
             "lookahead_distance": 2.5}',
 'Half the default thresholds: smoother seams, more relaxation', true),
('locomotion', '{"joints": ["pelvis", "left_hip", "left_knee", "left_ankle", "left_toe", "right_hip", "right_knee",
                 "right_ankle", "right_toe"],
                 "norm": "l1", "position_threshold": {"default": 0.15}, "angle_threshold": {"default": 0.5},
                 "velocity_threshold": {"default": 0.7}, "angular_velocity_threshold": {"default": 5.0},
                 "velocity_terms": true, "heading_weight": 0.3, "lookahead_distance": 2.5}',
 'Lower body only, L1 positions, and a heading term: for walking to goals', true)
ON CONFLICT (name) DO UPDATE SET settings = excluded.settings, comment = excluded.comment
 WHERE p.shipped;

-- 74_build.sql
CREATE OR REPLACE FUNCTION modb.build_snippets(collection text DEFAULT NULL, clip bigint DEFAULT NULL,
                                    window_seconds float8 DEFAULT 0.5, stride_seconds float8 DEFAULT 1.0 / 30,
                                    mirrored boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
kernel = GD.get('modb_kernel 0.7.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.cost_to_go': '"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of graph\nsnippets needs from that snippet\'s end until the pelvis is within the arrival radius of a goal, for goals\non a polar grid around that end (in its heading frame: x left, z forward).\n\nWhy: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind the\navatar when every successor of a straight walk goes straight, and circles a near goal. The cost-to-go\ncounts the turns the data can make after the candidate, however many snippets they take (as in\nnear-optimal controllers over motion graphs), so select_next_snippet\'s stored-transition level ranks by\n"seconds to the goal through this candidate" in one indexed lookup per candidate.\n\nComputed by value iteration (Bellman): V(s, g) = min over successors t of s of\nduration(t) + seam(s, t) + V(t, g seen from t\'s end), V = 0 within the arrival radius. seam(s, t) is the\ntransition\'s continuity ratio times the profile\'s continuity_weight / speed: the price the selection puts on\na rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals are read by\nbilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring\'s value plus the\nextra distance at the graph\'s median speed. The SQL reader is modb.cost_to_go, the same arithmetic.\n"""\nfrom dataclasses import asdict, dataclass\n\nimport numpy as np\n\nTOLERANCE = 0.01  # seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of convergence)\nMAX_ITERATIONS = 300\nMIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move\nEDGE_CHUNK = 4000  # sources per gather: bounds memory at about chunk x mean out-degree x grid size\n\n\n@dataclass(frozen=True)\nclass Grid:\n    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left) times\n    `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices the distance\n    beyond the outer ring. Values are stored angle-major: index angle * rings + ring."""\n    speed: float\n    angles: int = 24\n    rings: int = 11\n    inner_radius: float = 0.5\n    outer_radius: float = 12.0\n\n    def radii(self) -> np.ndarray:\n        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (np.arange(self.rings) / (self.rings - 1))\n\n    def points(self) -> tuple[np.ndarray, np.ndarray]:\n        """(x, z) of every grid point, in storage order."""\n        theta = np.arange(self.angles) * 2 * np.pi / self.angles\n        r = self.radii()\n        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()\n\n    def as_json(self) -> dict:\n        return asdict(self)\n\n\ndef interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):\n    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds added\n    beyond the outer ring. Goals within the inner radius get weights 0: reached."""\n    r = np.hypot(x, z)\n    ring = np.log(np.maximum(r, 1e-9) / grid.inner_radius) / np.log(grid.outer_radius / grid.inner_radius) * (grid.rings - 1)\n    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)\n    j0 = np.floor(ring).astype(np.int64)\n    wj = ring - j0\n    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)\n    a0 = np.floor(angle).astype(np.int64) % grid.angles\n    a1 = (a0 + 1) % grid.angles\n    wa = angle - np.floor(angle)\n    index = np.stack([a0 * grid.rings + j0, a0 * grid.rings + j0 + 1, a1 * grid.rings + j0, a1 * grid.rings + j0 + 1], -1)\n    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)\n    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed\n    reached = r <= grid.inner_radius\n    weight[reached] = 0\n    beyond[reached] = 0\n    return index, weight.astype(np.float32), beyond.astype(np.float32)\n\n\ndef seen_from_end(net_x, net_z, heading, x, z):\n    """Points (x, z) of a snippet\'s start frame seen from its end (modb.world_to_local): per snippet rows."""\n    dx = x[None, :] - np.asarray(net_x)[:, None]\n    dz = z[None, :] - np.asarray(net_z)[:, None]\n    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]\n    return dx * c - dz * s, dx * s + dz * c\n\n\ndef cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):\n    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.\n    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides the\n    duration of dst; a snippet without successors gets infinity."""\n    n = len(duration)\n    size = grid.angles * grid.rings\n    gx, gz = grid.points()\n    index, weight, beyond = interpolation(grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz))\n    index += (np.arange(n) * size)[:, None, None]  # into the flattened values\n    duration = np.asarray(duration, dtype=np.float32)[:, None]\n    order = np.argsort(src, kind="stable")\n    src, dst = np.asarray(src)[order], np.asarray(dst)[order]\n    seam = np.asarray(seam, dtype=np.float32)[order][:, None]\n    starts = np.r_[0, np.flatnonzero(np.diff(src)) + 1] if len(src) else np.zeros(0, dtype=np.int64)\n    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0\n    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.\n    values = np.tile(np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)).astype(np.float32)\n    values[:, ring0] = 0\n    change = np.inf\n    for iteration in range(1, MAX_ITERATIONS + 1):\n        through = duration + (values.ravel()[index] * weight).sum(-1) + beyond  # via each snippet as the next\n        new = np.full_like(values, np.inf)\n        for lo in range(0, len(starts), EDGE_CHUNK):\n            first = starts[lo:lo + EDGE_CHUNK]\n            stop = starts[lo + EDGE_CHUNK] if lo + EDGE_CHUNK < len(starts) else len(src)\n            new[src[first]] = np.minimum.reduceat(through[dst[first[0]:stop]] + seam[first[0]:stop], first - first[0], axis=0)\n        new[:, ring0] = 0\n        finite = np.isfinite(new)\n        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0\n        values = new\n        if progress:\n            progress(iteration, change)\n        if change < TOLERANCE:\n            break\n    return values, iteration, change\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The mirrored\njoint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how m(c)\'s frame sits\nagainst c\'s in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c (S R_root M_root at the\nroot), and a translated joint\'s translation becomes M_j t (S t at the root). Positions are exact whatever\nM is, as far as the captured skeleton is symmetric; rotations are what the same rig would report for the\nmirrored motion only with the rig\'s own M, and only then can mirrored snippets follow captured ones.\n\nFinding M_c. Every candidate must map c\'s child offsets (and end site, and translations that never change)\nonto its partner\'s: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates are the 24\nsigned permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where that leaves a choice\n(a bone\'s twist is invisible in its offsets):\n- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body\'s left-right axis as\n  seen in that frame (the principal axis of the hips\' and clavicles\' separations over the clip, which no yaw\n  or gesture changes) if it lies within 30 degrees of one; else, as in a joint that does not turn with the\n  body (a root above the pelvis), or a head held turned for a whole clip, it keeps its parent\'s;\n- a paired joint keeps its parent\'s M where that fits (a rig whose frames follow its symmetry: CMU\'s ASF,\n  S everywhere), else -I where that fits (a Maya-style rig mirrors the right side\'s axes as a whole);\n- anything else takes the candidate whose mirrored rotations come nearest, on average, to the partner\'s.\nA rig that is not axis-aligned gets the best fit of its offsets instead.\n"""\nimport itertools\n\nimport numpy as np\n\nfrom . import kinematics, quaternion\n\nWORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])\n# A captured skeleton\'s two sides differ by a few degrees (CMU 131\'s neck leans 7 degrees): within this the\n# axis-aligned convention is taken as the rig\'s, and the difference as capture asymmetry.\nALIGNED_COS = np.cos(np.radians(15.0))\nLATERAL_STEADINESS = 0.8  # share of the separations\' spread along the axis it takes to be one\nSTEADY_TRANSLATION = 1e-3  # relative spread under which a translation channel counts as a fixed offset\n\n\ndef _axis_aligned_reflections():\n    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror convention."""\n    out = []\n    for perm in itertools.permutations(range(3)):\n        for signs in itertools.product((1.0, -1.0), repeat=3):\n            m = np.zeros((3, 3))\n            m[list(perm), range(3)] = signs\n            if np.linalg.det(m) < 0:\n                out.append(m)\n    return out\n\n\nCANDIDATES = _axis_aligned_reflections()\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _unit(v):\n    v = np.asarray(v, dtype=np.float64)\n    norm = np.linalg.norm(v)\n    return v / norm if norm > 1e-9 else None\n\n\ndef _flips_one_axis(m):\n    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)\n\n\ndef _turning(a, b):\n    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when opposite)."""\n    axis = np.cross(a, b)\n    s, c = np.linalg.norm(axis), float(np.dot(a, b))\n    if s < 1e-12:\n        if c > 0:\n            return np.eye(3)\n        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0\n    axis = axis / np.linalg.norm(axis)\n    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])\n    return np.eye(3) + s * k + (1.0 - c) * (k @ k)\n\n\ndef _improper_fit(sources, targets):\n    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets (Kabsch)."""\n    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))\n    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt\n\n\ndef _fixed_offsets(offsets, translations, translated):\n    """Offsets, with those of translated joints whose translation never changes taken from it."""\n    offsets = np.array(offsets, dtype=np.float64)\n    for k, j in enumerate(translated):\n        t = np.asarray(translations, dtype=np.float64)[:, k]\n        mean = t.mean(axis=0)\n        offsets[j] = mean if np.abs(t - mean).max() <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0\n    return offsets\n\n\ndef _direction_pairs(j, children, offsets, end_sites, partner):\n    """(direction, partner\'s direction) of j\'s child offsets and end site, where both are non-zero."""\n    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]\n    if end_sites[j] is not None and end_sites[partner[j]] is not None:\n        pairs.append((end_sites[j], end_sites[partner[j]]))\n    units = [(_unit(a), _unit(b)) for a, b in pairs]\n    return [(a, b) for a, b in units if a is not None and b is not None]\n\n\ndef _lateral_axes(parents, positions, orientations, partner):\n    """Per joint, the body\'s left-right axis in the joint\'s own frame: the principal axis of the separations\n    of the pairs hung from one unpaired parent (hips, clavicles; or the first pair below them that is apart),\n    over all frames; zero where no axis holds (a root above the pelvis that does not turn with the body)."""\n    pairs = []\n    for c, m in enumerate(partner):\n        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:\n            while np.linalg.norm(positions[:, c] - positions[:, m], axis=-1).mean() < 1e-3:  # CMU\'s hip joints\n                below = [k for k in range(len(parents)) if parents[k] == c]\n                if not below:\n                    break\n                c, m = below[0], partner[below[0]]\n            pairs.append((c, m))\n    if not pairs:\n        return np.zeros((len(parents), 3))\n    separation = positions[:, [c for c, _ in pairs]] - positions[:, [m for _, m in pairs]]  # (F, P, 3)\n    separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)\n    local = quaternion.rotate(quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :])\n    values, vectors = np.linalg.eigh(np.einsum("fjpa,fjpb->jab", local, local))  # (J, 3, 3) scatter\n    steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)\n    turning = np.abs(orientations - orientations[:1]).max(axis=(0, 2)) > 1e-9  # a fixed frame is the world\'s\n    return vectors[:, :, -1] * (steady & turning)[:, None]\n\n\ndef _nearest_flip(candidates, axis):\n    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned for a\n    whole clip is no evidence of its frame)."""\n    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|\n    return best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None\n\n\ndef frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):\n    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3); mean_rotations:\n    (J, 3, 3) averages of the clip\'s parent-relative rotation matrices."""\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    out = np.empty((n_joints, 3, 3))\n    for j in range(n_joints):  # parents come before children\n        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one\'s\n            out[j] = out[partner[j]].T\n            continue\n        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]\n        pairs = _direction_pairs(j, children, offsets, end_sites, partner)\n        candidates = [m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)]\n        if partner[j] == j:\n            candidates = [m for m in candidates if _flips_one_axis(m)]\n        if not candidates:  # not axis-aligned: fit the offsets\n            sources = np.array([a for a, _ in pairs])\n            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:\n                out[j] = _improper_fit(sources, [b for _, b in pairs])\n                continue\n            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]\n        if len(candidates) == 1:\n            out[j] = candidates[0]\n        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:\n            out[j] = flip\n        elif any(np.allclose(m, above) for m in candidates):\n            out[j] = above\n        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):\n            out[j] = -np.eye(3)\n        else:\n            target = mean_rotations[partner[j]]\n            out[j] = min(candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target))\n    return out\n\n\ndef clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """M_j of every joint, found from a clip of the skeleton (see the module docstring)."""\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    return frame_reflections(parents, _fixed_offsets(offsets, translations, translated), end_sites, partner,\n                             _lateral_axes(parents, positions, orientations, partner),\n                             quaternion.to_matrix(rotations).mean(axis=0))\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    frames = clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated)\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = WORLD_REFLECTION if p < 0 else frames[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])\n    if not len(translated):\n        return out_rotations, translations\n    translations = np.asarray(translations, dtype=np.float64)\n    out_translations = np.empty_like(translations)\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]\n        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef conjugate(q):\n    """The inverse of unit quaternions: the same axis, the opposite angle."""\n    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = quaternion.conjugate(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.transitions': '"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and the\npart of it a chain can keep moving and steering in: the largest strongly connected component (as in\nmotion graphs) that holds turns both ways.\n\nOutside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a\ncomponent it cannot leave that never turns (in Bandai dataset 2, the runs: from a run\'s end only runs\npass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to the\nsteerable component keeps every chain where it can face its next goal.\n\nThe edge test is select_next_snippets\' level 0, computed for all pairs at once: the same search box\naround the end\'s features, the same per-joint ratio (position by the norm, rotation angle, velocities)\nwith the same float4 arithmetic, and the same rule against replaying the previous snippet\'s frames.\nNeeds scipy (the server: Debian\'s python3-scipy) for the box search and the components.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\nBOX_MARGIN = 1e-4  # match_box\'s margin: terminators store float4, features float8\n\n\nclass Terminators:\n    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19, 4)\n    as stored (float4), and features (n, 25)."""\n\n    def __init__(self, positions, rotations, velocities, angular_velocities, features):\n        n = len(features)\n        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)\n        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)\n        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)\n\n\ndef _norm(a, b, norm):\n    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens\n    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))\n\n\ndef _joint_terms(term, src, dst, plan, j):\n    """Joint j\'s continuity terms for pairs (end terminator src[k], begin terminator dst[k]): (difference,\n    threshold) for the rotation angle, the position (the plan\'s norm) and, with velocity terms, the\n    velocity and angular velocity."""\n    yield quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]), plan["angle_threshold"][j]\n    yield _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]), plan["position_threshold"][j]\n    if plan["velocity_terms"]:\n        yield _norm(term.velocities[src, j], term.velocities[dst, j], "l2"), plan["velocity_threshold"][j]\n        yield (_norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),\n               plan["angular_velocity_threshold"][j])\n\n\ndef _within(term, src, dst, plan):\n    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio is at\n    most 1. Joint by joint, the tightest first, so most pairs are dropped after one or two joints."""\n    keep = np.ones(len(src), dtype=bool)\n    order = sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j])\n    for j in order:\n        s, d = src[keep], dst[keep]\n        ok = np.ones(len(s), dtype=bool)\n        for difference, threshold in _joint_terms(term, s, d, plan, j):\n            ok &= difference <= threshold\n        keep[np.flatnonzero(keep)[~ok]] = False\n    return keep\n\n\ndef ratios(term, src, dst, plan):\n    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest over the\n    plan\'s joints and terms of difference / threshold (select_next_snippets\' continuity_ratio)."""\n    ratio = np.zeros(len(src))\n    for j in plan["joints"]:\n        for difference, threshold in _joint_terms(term, src, dst, plan, j):\n            ratio = np.maximum(ratio, difference / threshold)\n    return ratio\n\n\ndef edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):\n    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets given by\n    their begin and end terminator rows in `term`, their pose/rate group, clip (and version, mirror: one key)\n    and window. progress(done) is called after each chunk of sources."""\n    from scipy.spatial import cKDTree\n\n    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN\n    out_src, out_dst, out_ratio = [], [], []\n    done = 0\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        tree = cKDTree(term.features[begin[members]] / half)\n        for lo in range(0, len(members), chunk):\n            sources = members[lo:lo + chunk]\n            done += len(sources)\n            near = tree.query_ball_point(term.features[end[sources]] / half, r=1.0, p=np.inf)\n            counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))\n            if not counts.sum():\n                continue  # (progress is reported with the next chunk that has candidates)\n            s = np.repeat(sources, counts)\n            d = members[np.concatenate([np.asarray(c, dtype=np.int64) for c in near if len(c)])]\n            # No replay of the previous snippet\'s frames (its last frame, the seam, aside).\n            overlap = ((clip[s] == clip[d]) & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)\n                       & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1))\n            s, d = s[~overlap], d[~overlap]\n            keep = _within(term, end[s], begin[d], plan)\n            out_src.append(s[keep])\n            out_dst.append(d[keep])\n            out_ratio.append(ratios(term, end[s[keep]], begin[d[keep]], plan))\n            if progress:\n                progress(done)\n    if not out_src:\n        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)\n    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)\n\n\ndef steerable(n, src, dst, group, turn, min_turn):\n    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate group\n    among those (of more than one snippet) whose snippets include turns of at least min_turn radians each\n    way (`turn`: the heading change where each one leads). A chain in it can always move on, and can face\n    any goal. (The largest only, as in motion graphs: on Bandai dataset 2, adding the active walks\'\n    component to the slow walks\' made right-angle courses worse: README "Transition graphs".)"""\n    from scipy.sparse import coo_matrix\n    from scipy.sparse.csgraph import connected_components\n\n    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()\n    _, label = connected_components(graph, directed=True, connection="strong")\n    turn = np.asarray(turn, dtype=np.float64)\n    size = np.bincount(label, minlength=label.max() + 1)\n    left = np.zeros(len(size), dtype=bool)\n    right = np.zeros(len(size), dtype=bool)\n    np.logical_or.at(left, label, turn >= min_turn)\n    np.logical_or.at(right, label, turn <= -min_turn)\n    eligible = (size > 1) & left & right\n    keep = np.zeros(n, dtype=bool)\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        candidates = np.unique(label[members][eligible[label[members]]])\n        if len(candidates):\n            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True\n    return keep\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_7_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.7.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_7_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_7_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_7_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.7.0'] = kernel
import json
import numpy as np

T = kernel.terminators
if not (window_seconds and window_seconds > 0 and stride_seconds and stride_seconds > 0):
    plpy.error("window_seconds and stride_seconds must be positive")
collections = None
if collection is not None:
    collections = plpy.execute(plpy.prepare("SELECT modb.collection_subtree($1) AS ids", ["text"]), [collection])[0]["ids"]
    if not collections:
        plpy.error(f'no collection "{collection}"', hint="modb.collection_path(id) names the stored ones")
todo = plpy.cursor(plpy.prepare(
    """SELECT v.clip_id, v.version, v.fps, v.rotations, v.translations, s.id AS skeleton_id, s.hierarchy,
              s.joint_map, s.mirror_pairs, c.collection_id, c.name, modb.skeleton_pose_key(s.hierarchy) AS pose_key
         FROM modb.clip_versions v
         JOIN modb.clips c ON c.id = v.clip_id
         JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.version = (SELECT max(version) FROM modb.clip_versions x WHERE x.clip_id = v.clip_id)
          AND ($1::bigint[] IS NULL OR c.collection_id = ANY ($1))
          AND ($2::bigint IS NULL OR c.id = $2)
          AND NOT EXISTS (SELECT FROM modb.snippet_sources ss
                           WHERE ss.clip_id = v.clip_id AND ss.version = v.version AND ss.mirrored = $3)
        ORDER BY v.clip_id""", ["bigint[]", "bigint", "boolean"]), [collections, clip, bool(mirrored)])
drop_old = plpy.prepare(
    "DELETE FROM modb.snippet_sources WHERE clip_id = $1 AND version < $2 RETURNING mirrored", ["bigint", "int"])
built = plpy.prepare("SELECT mirrored FROM modb.snippet_sources WHERE clip_id = $1 AND version = $2",
                     ["bigint", "int"])
add_source = plpy.prepare(
    "INSERT INTO modb.snippet_sources (clip_id, version, mirrored, window_frames, stride_frames) "
    "VALUES ($1, $2, $5, $3, $4)", ["bigint", "int", "int", "int", "boolean"])
add_terminators = plpy.prepare(
    """INSERT INTO modb.terminators (clip_id, version, mirrored, frame, heading, pelvis_height, positions,
                                     rotations, velocities, angular_velocities, configuration, features)
       SELECT $1, $2, $4, r.frame, r.heading, r.pelvis_height, r.positions, r.rotations, r.velocities,
              r.angular_velocities, r.configuration, cube(r.features)
         FROM jsonb_to_recordset($3::jsonb) AS r(frame int, heading float8, pelvis_height real, positions real[],
              rotations real[], velocities real[], angular_velocities real[], configuration real[][], features float8[])
       RETURNING frame, id""", ["bigint", "int", "text", "boolean"])
add_snippets = plpy.prepare(
    """INSERT INTO modb.snippets (clip_id, version, mirrored, first_frame, n_frames, collection_id, pose_key, fps,
                                  begin_terminator, end_terminator, begin_features, net_translation, net_heading,
                                  net_rotation)
       SELECT $1, $2, $8, r.first_frame, $3, $4, $5, $6, r.begin_terminator, r.end_terminator, t.features,
              r.net_translation, r.net_heading, r.net_rotation
         FROM jsonb_to_recordset($7::jsonb) AS r(first_frame int, begin_terminator bigint, end_terminator bigint,
              net_translation float8[], net_heading float8, net_rotation float8[])
         JOIN modb.terminators t ON t.id = r.begin_terminator
        ORDER BY r.first_frame""",
    ["bigint", "int", "int", "bigint", "text", "float8", "text", "boolean"])

def flat(a):
    return np.asarray(a, dtype=np.float64).reshape(len(a), -1).tolist()

added = 0
while True:
    rows = todo.fetch(1)
    if not rows:
        break
    row = rows[0]
    h = json.loads(row["hierarchy"])
    names = [j["name"] for j in h["joints"]]
    try:
        std = T.standard_indices(names, json.loads(row["joint_map"]))
    except T.SkeletonMapError as e:
        plpy.error(f'clip {row["clip_id"]} ({row["name"]}): skeleton {row["skeleton_id"]}: {e}',
                   hint="complete modb.skeletons.joint_map for it, then call modb.build_snippets again")
    captured = np.asarray(row["rotations"], dtype=np.float64)
    firsts, length, stride = T.windows(len(captured), row["fps"], window_seconds, stride_seconds)
    # A new version replaces the old versions' snippets, and keeps their mirror images if they had them.
    old_flags = {r["mirrored"] for r in plpy.execute(drop_old, [row["clip_id"], row["version"]])}
    existing = {r["mirrored"] for r in plpy.execute(built, [row["clip_id"], row["version"]])}
    parents = [j["parent"] for j in h["joints"]]
    offsets = [j["offset"] for j in h["joints"]]
    for flag in sorted(({bool(mirrored)} | old_flags) - existing):
        plpy.execute(add_source, [row["clip_id"], row["version"], length, stride, flag])
        if len(firsts) == 0:
            continue  # shorter than one snippet: recorded as built, nothing to add
        rotations, translations = captured, row["translations"]
        if flag:
            pairs = json.loads(row["mirror_pairs"])
            if not pairs:
                plpy.error(f'clip {row["clip_id"]} ({row["name"]}): skeleton {row["skeleton_id"]} has no mirror pairs',
                           hint="fill modb.skeletons.mirror_pairs with its [left, right] joints")
            rotations, translations = kernel.mirror.mirror(
                parents, offsets, [j["end_site"] for j in h["joints"]], kernel.mirror.partner_index(names, pairs),
                rotations, translations, h["translated"])
        terms = T.compute(parents, offsets, rotations, translations, h["translated"], std, row["fps"])
        frames = sorted(set(firsts.tolist()) | set((firsts + length - 1).tolist()))
        pick = {k: flat(terms[k][frames]) for k in ("positions", "rotations", "velocities", "angular_velocities", "features")}
        configuration = terms["configuration"][frames].tolist()
        records = [{"frame": f, "heading": float(terms["heading"][f]), "pelvis_height": float(terms["pelvis_height"][f]),
                    "positions": pick["positions"][i], "rotations": pick["rotations"][i],
                    "velocities": pick["velocities"][i], "angular_velocities": pick["angular_velocities"][i],
                    "configuration": configuration[i], "features": pick["features"][i]}
                   for i, f in enumerate(frames)]
        ids = {r["frame"]: r["id"] for r in plpy.execute(add_terminators, [row["clip_id"], row["version"],
                                                                          json.dumps(records), flag])}
        snippets = []
        for first in firsts.tolist():
            last = first + length - 1
            translation, turn, rotation = T.net_motion(terms, first, last)
            snippets.append({"first_frame": first, "begin_terminator": ids[first], "end_terminator": ids[last],
                             "net_translation": translation.tolist(), "net_heading": float(turn),
                             "net_rotation": rotation.tolist()})
        plpy.execute(add_snippets, [row["clip_id"], row["version"], length, row["collection_id"], row["pose_key"],
                                    row["fps"], json.dumps(snippets), flag])
        added += len(snippets)
plpy.execute("SELECT modb.fill_futures()")  # after every clip's snippets exist: futures chain through them
return added
$py$;
COMMENT ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) IS
    'Cuts the newest version of every clip in scope (a collection''s subtree, one clip, or all) that has no snippets yet into windows of window_seconds starting every stride_seconds, with their terminators; drops the snippets of older versions. mirrored => true adds the clips'' mirror images (through the skeleton''s mirror_pairs) as further sources. Returns the number of snippets added';

REVOKE EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_snippets(text, bigint, float8, float8, boolean) TO modb_loader;

-- 75_graphs.sql
-- Transition graphs: which snippets a chain can keep moving and steering among (modb_kernel/transitions.py
-- says why).
-- A graph is a modb.graphs row (kind 'transitions': how it was built and what it holds, in jsonb) and
-- its snippets in modb.graph_snippets, which select_next_snippet reads when the `graph` knob names it.

CREATE TABLE modb.graph_snippets (
    graph_id   bigint NOT NULL REFERENCES modb.graphs (id) ON DELETE CASCADE,
    snippet_id bigint NOT NULL REFERENCES modb.snippets (id) ON DELETE CASCADE,
    PRIMARY KEY (graph_id, snippet_id)
);
COMMENT ON TABLE modb.graph_snippets IS
    'The snippets a transition graph keeps (its largest strongly connected component that turns both ways): with SET modb.graph = ''<name>'' (or "graph" in a profile) select_next_snippet chooses among these only';
CREATE INDEX graph_snippets_snippet_idx ON modb.graph_snippets (snippet_id);  -- for ON DELETE CASCADE
SELECT pg_catalog.pg_extension_config_dump('modb.graph_snippets', '');

CREATE OR REPLACE FUNCTION modb.build_transition_graph(name text, profile text DEFAULT 'default',
                                                       collection text DEFAULT NULL, min_turn_degrees float8 DEFAULT 45)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
kernel = GD.get('modb_kernel 0.7.0')
if kernel is None:
    import importlib, importlib.abc, importlib.util, sys
    class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
        sources = {
            'modb_kernel': '"""Numeric core shared by the Python client and the server\'s PL/Python functions.\n\nPlain numpy only (no numpy 2.x-only API): the server runs Debian\'s python3 with\nnumpy 1.24, the client whatever the virtualenv has. Inside PostgreSQL this\npackage is loaded from the extension\'s install script (see\n``extension/build_sql.py``), so the server always runs the code of the\ninstalled extension version.\n\nConventions (DESIGN.md): metres, seconds, radians; quaternions (w, x, y, z),\nunit length, w >= 0; a joint\'s rotation is relative to its parent.\n"""\n',
            'modb_kernel.cost_to_go': '"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of graph\nsnippets needs from that snippet\'s end until the pelvis is within the arrival radius of a goal, for goals\non a polar grid around that end (in its heading frame: x left, z forward).\n\nWhy: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind the\navatar when every successor of a straight walk goes straight, and circles a near goal. The cost-to-go\ncounts the turns the data can make after the candidate, however many snippets they take (as in\nnear-optimal controllers over motion graphs), so select_next_snippet\'s stored-transition level ranks by\n"seconds to the goal through this candidate" in one indexed lookup per candidate.\n\nComputed by value iteration (Bellman): V(s, g) = min over successors t of s of\nduration(t) + seam(s, t) + V(t, g seen from t\'s end), V = 0 within the arrival radius. seam(s, t) is the\ntransition\'s continuity ratio times the profile\'s continuity_weight / speed: the price the selection puts on\na rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals are read by\nbilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring\'s value plus the\nextra distance at the graph\'s median speed. The SQL reader is modb.cost_to_go, the same arithmetic.\n"""\nfrom dataclasses import asdict, dataclass\n\nimport numpy as np\n\nTOLERANCE = 0.01  # seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of convergence)\nMAX_ITERATIONS = 300\nMIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move\nEDGE_CHUNK = 4000  # sources per gather: bounds memory at about chunk x mean out-degree x grid size\n\n\n@dataclass(frozen=True)\nclass Grid:\n    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left) times\n    `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices the distance\n    beyond the outer ring. Values are stored angle-major: index angle * rings + ring."""\n    speed: float\n    angles: int = 24\n    rings: int = 11\n    inner_radius: float = 0.5\n    outer_radius: float = 12.0\n\n    def radii(self) -> np.ndarray:\n        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (np.arange(self.rings) / (self.rings - 1))\n\n    def points(self) -> tuple[np.ndarray, np.ndarray]:\n        """(x, z) of every grid point, in storage order."""\n        theta = np.arange(self.angles) * 2 * np.pi / self.angles\n        r = self.radii()\n        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()\n\n    def as_json(self) -> dict:\n        return asdict(self)\n\n\ndef interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):\n    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds added\n    beyond the outer ring. Goals within the inner radius get weights 0: reached."""\n    r = np.hypot(x, z)\n    ring = np.log(np.maximum(r, 1e-9) / grid.inner_radius) / np.log(grid.outer_radius / grid.inner_radius) * (grid.rings - 1)\n    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)\n    j0 = np.floor(ring).astype(np.int64)\n    wj = ring - j0\n    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)\n    a0 = np.floor(angle).astype(np.int64) % grid.angles\n    a1 = (a0 + 1) % grid.angles\n    wa = angle - np.floor(angle)\n    index = np.stack([a0 * grid.rings + j0, a0 * grid.rings + j0 + 1, a1 * grid.rings + j0, a1 * grid.rings + j0 + 1], -1)\n    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)\n    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed\n    reached = r <= grid.inner_radius\n    weight[reached] = 0\n    beyond[reached] = 0\n    return index, weight.astype(np.float32), beyond.astype(np.float32)\n\n\ndef seen_from_end(net_x, net_z, heading, x, z):\n    """Points (x, z) of a snippet\'s start frame seen from its end (modb.world_to_local): per snippet rows."""\n    dx = x[None, :] - np.asarray(net_x)[:, None]\n    dz = z[None, :] - np.asarray(net_z)[:, None]\n    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]\n    return dx * c - dz * s, dx * s + dz * c\n\n\ndef cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):\n    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.\n    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides the\n    duration of dst; a snippet without successors gets infinity."""\n    n = len(duration)\n    size = grid.angles * grid.rings\n    gx, gz = grid.points()\n    index, weight, beyond = interpolation(grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz))\n    index += (np.arange(n) * size)[:, None, None]  # into the flattened values\n    duration = np.asarray(duration, dtype=np.float32)[:, None]\n    order = np.argsort(src, kind="stable")\n    src, dst = np.asarray(src)[order], np.asarray(dst)[order]\n    seam = np.asarray(seam, dtype=np.float32)[order][:, None]\n    starts = np.r_[0, np.flatnonzero(np.diff(src)) + 1] if len(src) else np.zeros(0, dtype=np.int64)\n    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0\n    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.\n    values = np.tile(np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)).astype(np.float32)\n    values[:, ring0] = 0\n    change = np.inf\n    for iteration in range(1, MAX_ITERATIONS + 1):\n        through = duration + (values.ravel()[index] * weight).sum(-1) + beyond  # via each snippet as the next\n        new = np.full_like(values, np.inf)\n        for lo in range(0, len(starts), EDGE_CHUNK):\n            first = starts[lo:lo + EDGE_CHUNK]\n            stop = starts[lo + EDGE_CHUNK] if lo + EDGE_CHUNK < len(starts) else len(src)\n            new[src[first]] = np.minimum.reduceat(through[dst[first[0]:stop]] + seam[first[0]:stop], first - first[0], axis=0)\n        new[:, ring0] = 0\n        finite = np.isfinite(new)\n        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0\n        values = new\n        if progress:\n            progress(iteration, change)\n        if change < TOLERANCE:\n            break\n    return values, iteration, change\n',
            'modb_kernel.joints': '"""Standard joint names: what a skeleton\'s joint map maps onto its own joints (DESIGN.md, "Joint map")."""\n\nSTANDARD_JOINTS = (\n    "pelvis", "spine", "chest", "neck", "head",\n    "left_hip", "left_knee", "left_ankle", "left_toe", "left_shoulder", "left_elbow", "left_wrist",\n    "right_hip", "right_knee", "right_ankle", "right_toe", "right_shoulder", "right_elbow", "right_wrist",\n)\n\n# The indexed feature vector (terminators.py): pelvis height, these joints\' positions, these joints\'\n# velocities, all in the local heading frame, physical units.\nFEATURE_POSITIONS = ("head", "left_wrist", "right_wrist", "left_ankle", "right_ankle")\nFEATURE_VELOCITIES = ("pelvis", "left_ankle", "right_ankle")\nFEATURES = (["pelvis.y"] + [f"{j}.{a}" for j in FEATURE_POSITIONS for a in "xyz"]\n            + [f"{j}.v{a}" for j in FEATURE_VELOCITIES for a in "xyz"])\n',
            'modb_kernel.kinematics': '"""Forward kinematics: the same code for every source format (BVH and ASF/AMC)."""\nimport numpy as np\n\nfrom . import quaternion\n\n\ndef world_positions(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) of every joint\'s origin (see world_transforms)."""\n    return world_transforms(parents, offsets, rotations, translations, translated)[0]\n\n\ndef world_transforms(parents, offsets, rotations, translations=None, translated=()):\n    """World positions (frames, joints, 3) and orientations (frames, joints, 4) of every joint.\n\n    parents: parent index per joint (-1 for the root), parents listed before children.\n    offsets: (joints, 3) rest offsets from the parent, metres.\n    rotations: (frames, joints, 4) unit quaternions relative to the parent.\n    translations: (frames, len(translated), 3) local translations that replace the\n    offsets of the joints listed in `translated` (joints with position channels).\n    """\n    rotations = np.asarray(rotations, dtype=np.float64)\n    n_frames, n_joints = rotations.shape[:2]\n    local = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (n_frames, n_joints, 3)).copy()\n    if len(translated):\n        local[:, list(translated), :] = np.asarray(translations, dtype=np.float64)\n    positions = np.empty((n_frames, n_joints, 3))\n    orientations = np.empty((n_frames, n_joints, 4))\n    for j, p in enumerate(parents):\n        if p < 0:\n            positions[:, j] = local[:, j]\n            orientations[:, j] = rotations[:, j]\n        else:\n            positions[:, j] = positions[:, p] + quaternion.rotate(orientations[:, p], local[:, j])\n            orientations[:, j] = quaternion.multiply(orientations[:, p], rotations[:, j])\n    return positions, orientations\n\n\ndef rest_positions(parents, offsets):\n    """World positions (joints, 3) with every rotation the identity."""\n    offsets = np.asarray(offsets, dtype=np.float64)\n    out = np.zeros_like(offsets)\n    for j, p in enumerate(parents):\n        out[j] = offsets[j] if p < 0 else out[p] + offsets[j]\n    return out\n',
            'modb_kernel.mirror': '"""Mirroring a clip through the skeleton\'s left/right pairing: the same motion as if captured in a mirror.\n\nWorld positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The mirrored\njoint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how m(c)\'s frame sits\nagainst c\'s in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c (S R_root M_root at the\nroot), and a translated joint\'s translation becomes M_j t (S t at the root). Positions are exact whatever\nM is, as far as the captured skeleton is symmetric; rotations are what the same rig would report for the\nmirrored motion only with the rig\'s own M, and only then can mirrored snippets follow captured ones.\n\nFinding M_c. Every candidate must map c\'s child offsets (and end site, and translations that never change)\nonto its partner\'s: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates are the 24\nsigned permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where that leaves a choice\n(a bone\'s twist is invisible in its offsets):\n- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body\'s left-right axis as\n  seen in that frame (the principal axis of the hips\' and clavicles\' separations over the clip, which no yaw\n  or gesture changes) if it lies within 30 degrees of one; else, as in a joint that does not turn with the\n  body (a root above the pelvis), or a head held turned for a whole clip, it keeps its parent\'s;\n- a paired joint keeps its parent\'s M where that fits (a rig whose frames follow its symmetry: CMU\'s ASF,\n  S everywhere), else -I where that fits (a Maya-style rig mirrors the right side\'s axes as a whole);\n- anything else takes the candidate whose mirrored rotations come nearest, on average, to the partner\'s.\nA rig that is not axis-aligned gets the best fit of its offsets instead.\n"""\nimport itertools\n\nimport numpy as np\n\nfrom . import kinematics, quaternion\n\nWORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])\n# A captured skeleton\'s two sides differ by a few degrees (CMU 131\'s neck leans 7 degrees): within this the\n# axis-aligned convention is taken as the rig\'s, and the difference as capture asymmetry.\nALIGNED_COS = np.cos(np.radians(15.0))\nLATERAL_STEADINESS = 0.8  # share of the separations\' spread along the axis it takes to be one\nSTEADY_TRANSLATION = 1e-3  # relative spread under which a translation channel counts as a fixed offset\n\n\ndef _axis_aligned_reflections():\n    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror convention."""\n    out = []\n    for perm in itertools.permutations(range(3)):\n        for signs in itertools.product((1.0, -1.0), repeat=3):\n            m = np.zeros((3, 3))\n            m[list(perm), range(3)] = signs\n            if np.linalg.det(m) < 0:\n                out.append(m)\n    return out\n\n\nCANDIDATES = _axis_aligned_reflections()\n\n\ndef partner_index(names, pairs):\n    index = {n: k for k, n in enumerate(names)}\n    partner = list(range(len(names)))\n    for left, right in pairs:\n        partner[index[left]], partner[index[right]] = index[right], index[left]\n    return partner\n\n\ndef _unit(v):\n    v = np.asarray(v, dtype=np.float64)\n    norm = np.linalg.norm(v)\n    return v / norm if norm > 1e-9 else None\n\n\ndef _flips_one_axis(m):\n    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)\n\n\ndef _turning(a, b):\n    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when opposite)."""\n    axis = np.cross(a, b)\n    s, c = np.linalg.norm(axis), float(np.dot(a, b))\n    if s < 1e-12:\n        if c > 0:\n            return np.eye(3)\n        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0\n    axis = axis / np.linalg.norm(axis)\n    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])\n    return np.eye(3) + s * k + (1.0 - c) * (k @ k)\n\n\ndef _improper_fit(sources, targets):\n    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets (Kabsch)."""\n    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))\n    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt\n\n\ndef _fixed_offsets(offsets, translations, translated):\n    """Offsets, with those of translated joints whose translation never changes taken from it."""\n    offsets = np.array(offsets, dtype=np.float64)\n    for k, j in enumerate(translated):\n        t = np.asarray(translations, dtype=np.float64)[:, k]\n        mean = t.mean(axis=0)\n        offsets[j] = mean if np.abs(t - mean).max() <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0\n    return offsets\n\n\ndef _direction_pairs(j, children, offsets, end_sites, partner):\n    """(direction, partner\'s direction) of j\'s child offsets and end site, where both are non-zero."""\n    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]\n    if end_sites[j] is not None and end_sites[partner[j]] is not None:\n        pairs.append((end_sites[j], end_sites[partner[j]]))\n    units = [(_unit(a), _unit(b)) for a, b in pairs]\n    return [(a, b) for a, b in units if a is not None and b is not None]\n\n\ndef _lateral_axes(parents, positions, orientations, partner):\n    """Per joint, the body\'s left-right axis in the joint\'s own frame: the principal axis of the separations\n    of the pairs hung from one unpaired parent (hips, clavicles; or the first pair below them that is apart),\n    over all frames; zero where no axis holds (a root above the pelvis that does not turn with the body)."""\n    pairs = []\n    for c, m in enumerate(partner):\n        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:\n            while np.linalg.norm(positions[:, c] - positions[:, m], axis=-1).mean() < 1e-3:  # CMU\'s hip joints\n                below = [k for k in range(len(parents)) if parents[k] == c]\n                if not below:\n                    break\n                c, m = below[0], partner[below[0]]\n            pairs.append((c, m))\n    if not pairs:\n        return np.zeros((len(parents), 3))\n    separation = positions[:, [c for c, _ in pairs]] - positions[:, [m for _, m in pairs]]  # (F, P, 3)\n    separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)\n    local = quaternion.rotate(quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :])\n    values, vectors = np.linalg.eigh(np.einsum("fjpa,fjpb->jab", local, local))  # (J, 3, 3) scatter\n    steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)\n    turning = np.abs(orientations - orientations[:1]).max(axis=(0, 2)) > 1e-9  # a fixed frame is the world\'s\n    return vectors[:, :, -1] * (steady & turning)[:, None]\n\n\ndef _nearest_flip(candidates, axis):\n    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned for a\n    whole clip is no evidence of its frame)."""\n    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|\n    return best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None\n\n\ndef frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):\n    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3); mean_rotations:\n    (J, 3, 3) averages of the clip\'s parent-relative rotation matrices."""\n    n_joints = len(parents)\n    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]\n    out = np.empty((n_joints, 3, 3))\n    for j in range(n_joints):  # parents come before children\n        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one\'s\n            out[j] = out[partner[j]].T\n            continue\n        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]\n        pairs = _direction_pairs(j, children, offsets, end_sites, partner)\n        candidates = [m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)]\n        if partner[j] == j:\n            candidates = [m for m in candidates if _flips_one_axis(m)]\n        if not candidates:  # not axis-aligned: fit the offsets\n            sources = np.array([a for a, _ in pairs])\n            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:\n                out[j] = _improper_fit(sources, [b for _, b in pairs])\n                continue\n            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]\n        if len(candidates) == 1:\n            out[j] = candidates[0]\n        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:\n            out[j] = flip\n        elif any(np.allclose(m, above) for m in candidates):\n            out[j] = above\n        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):\n            out[j] = -np.eye(3)\n        else:\n            target = mean_rotations[partner[j]]\n            out[j] = min(candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target))\n    return out\n\n\ndef clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """M_j of every joint, found from a clip of the skeleton (see the module docstring)."""\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    return frame_reflections(parents, _fixed_offsets(offsets, translations, translated), end_sites, partner,\n                             _lateral_axes(parents, positions, orientations, partner),\n                             quaternion.to_matrix(rotations).mean(axis=0))\n\n\ndef mirror(parents, offsets, end_sites, partner, rotations, translations, translated):\n    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    frames = clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated)\n    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)\n    out_rotations = np.empty_like(rotations)\n    for c, p in enumerate(parents):\n        above = WORLD_REFLECTION if p < 0 else frames[p]\n        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])\n    if not len(translated):\n        return out_rotations, translations\n    translations = np.asarray(translations, dtype=np.float64)\n    out_translations = np.empty_like(translations)\n    slot = {j: k for k, j in enumerate(translated)}\n    for k, c in enumerate(translated):\n        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]\n        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T\n    return out_rotations, out_translations\n',
            'modb_kernel.quaternion': '"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""\nimport numpy as np\n\n_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}\n\n\ndef canonical(q):\n    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""\n    q = np.asarray(q, dtype=np.float64)\n    q = q / np.linalg.norm(q, axis=-1, keepdims=True)\n    return np.where(q[..., :1] < 0.0, -q, q)\n\n\ndef conjugate(q):\n    """The inverse of unit quaternions: the same axis, the opposite angle."""\n    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])\n\n\ndef multiply(a, b):\n    """Hamilton product a * b (apply b first, then a)."""\n    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)\n    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            aw * bw - ax * bx - ay * by - az * bz,\n            aw * bx + ax * bw + ay * bz - az * by,\n            aw * by - ax * bz + ay * bw + az * bx,\n            aw * bz + ax * by - ay * bx + az * bw,\n        ],\n        axis=-1,\n    )\n\n\ndef rotate(q, v):\n    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""\n    q = np.asarray(q, dtype=np.float64)\n    v = np.asarray(v, dtype=np.float64)\n    w = q[..., :1]\n    u = q[..., 1:]\n    t = 2.0 * np.cross(u, v)\n    return v + w * t + np.cross(u, t)\n\n\ndef about_axis(axis, angle):\n    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis \'X\', \'Y\' or \'Z\'."""\n    angle = np.asarray(angle, dtype=np.float64)\n    q = np.zeros(angle.shape + (4,))\n    q[..., 0] = np.cos(angle / 2.0)\n    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)\n    return q\n\n\ndef from_euler(angles, order):\n    """Quaternions from Euler angles (radians, shape (..., len(order))).\n\n    `order` lists the axes as the channels do, e.g. \'ZXY\' for BVH channels\n    \'Zrotation Xrotation Yrotation\': R = Rz(a0) * Rx(a1) * Ry(a2), so the\n    rightmost axis is applied to the vector first (intrinsic rotations).\n    """\n    angles = np.asarray(angles, dtype=np.float64)\n    q = np.zeros(angles.shape[:-1] + (4,))\n    q[..., 0] = 1.0\n    for i, axis in enumerate(order):\n        q = multiply(q, about_axis(axis, angles[..., i]))\n    return canonical(q)\n\n\ndef to_matrix(q):\n    """Rotation matrices (..., 3, 3) from unit quaternions."""\n    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)\n    return np.stack(\n        [\n            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),\n            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),\n            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),\n        ],\n        axis=-2,\n    )\n\n\ndef is_supported_order(order):\n    """Euler orders we can both read and write back: up to three distinct axes."""\n    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)\n\n\ndef to_euler(q, order):\n    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.\n\n    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the\n    rotation is assumed to have no component about the missing axes (true for\n    data read through those channels) and each angle keeps its full range.\n    """\n    if not is_supported_order(order):\n        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")\n    r = to_matrix(q)\n    if len(order) == 1:\n        i = _AXIS_INDEX[order]\n        j, k = (i + 1) % 3, (i + 2) % 3\n        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]\n    full = order + "".join(a for a in "XYZ" if a not in order)\n    i, j, k = (_AXIS_INDEX[a] for a in full)\n    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).\n    s = 1.0 if (j - i) % 3 == 1 else -1.0\n    if len(order) == 2:\n        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).\n        a = np.arctan2(s * r[..., k, j], r[..., j, j])\n        b = np.arctan2(s * r[..., i, k], r[..., i, i])\n        return np.stack([a, b], axis=-1)\n    cos_b = np.hypot(r[..., i, i], r[..., i, j])\n    b = np.arctan2(s * r[..., i, k], cos_b)\n    a = np.arctan2(-s * r[..., j, k], r[..., k, k])\n    c = np.arctan2(-s * r[..., i, j], r[..., i, i])\n    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with\n    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.\n    locked = cos_b < 1e-9\n    if np.any(locked):\n        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)\n        c = np.where(locked, 0.0, c)\n    return np.stack([a, b, c], axis=-1)\n\n\ndef angle_between(a, b):\n    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""\n    a = np.asarray(a, dtype=np.float64)\n    b = np.asarray(b, dtype=np.float64)\n    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)\n    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the\n    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b) does not.\n    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))\n\n\ndef from_matrix(m):\n    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd\'s method, w >= 0)."""\n    m = np.asarray(m, dtype=np.float64)\n    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]\n    cands = np.stack([\n        np.stack([1 + t, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),\n        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + 2 * m[..., 0, 0] - t, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),\n        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 + 2 * m[..., 1, 1] - t, m[..., 1, 2] + m[..., 2, 1]], -1),\n        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 + 2 * m[..., 2, 2] - t], -1),\n    ], axis=-2)\n    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.\n    best = np.argmax(np.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1), -1)\n    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]\n    return canonical(q)\n',
            'modb_kernel.terminators': '"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per clip.\n\nDefinitions (README "Snippets and terminators" documents them; tests re-derive them independently):\n- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a character\'s\n  +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S * fps) frames (cut at\n  the clip\'s ends) because the pelvis yaws with every step; theta = atan2(f_x, f_z).\n- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by theta\n  about +Y. Positions and velocities of the standard joints are expressed in it.\n- Rotations: the pelvis\'s orientation in the heading frame (its tilt and residual yaw); every other\n  joint\'s rotation relative to its parent.\n- Velocities: central differences over the neighbouring frames (one-sided at the clip\'s ends), in the\n  frame\'s heading frame. Angular velocity: the pelvis\'s world angular velocity in the heading frame; other\n  joints\' from their parent-relative rotations, in their own frame.\n- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles positions;\n  pelvis and ankles velocities (FEATURES lists the 25 dimensions).\n"""\nimport numpy as np\n\nfrom . import kinematics, quaternion\nfrom .joints import FEATURE_POSITIONS, FEATURE_VELOCITIES, STANDARD_JOINTS\n\nHEADING_HALF_WINDOW_S = 0.25\n\n\nclass SkeletonMapError(ValueError):\n    pass\n\n\ndef standard_indices(names, joint_map):\n    """Joint index of every standard joint; all must be mapped."""\n    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]\n    if missing:\n        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))\n    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]\n\n\ndef _about_y(theta):\n    return quaternion.about_axis("Y", theta)\n\n\ndef _rotvec(q):\n    """Rotation vectors (axis * angle) of quaternions."""\n    q = quaternion.canonical(q)\n    v = q[..., 1:]\n    s = np.linalg.norm(v, axis=-1, keepdims=True)\n    angle = 2.0 * np.arctan2(s, q[..., :1])\n    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)\n\n\ndef _neighbours(n):\n    """Indices (before, after) and their time span in frames, for central differences."""\n    before = np.clip(np.arange(n) - 1, 0, n - 1)\n    after = np.clip(np.arange(n) + 1, 0, n - 1)\n    return before, after, np.maximum(after - before, 1)\n\n\ndef headings(positions, left_hip, right_hip, fps):\n    l = positions[:, left_hip] - positions[:, right_hip]\n    forward = np.stack([-l[:, 2], np.zeros(len(l)), l[:, 0]], axis=-1)\n    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)\n    half = int(round(HEADING_HALF_WINDOW_S * fps))\n    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])\n    lo = np.clip(np.arange(len(l)) - half, 0, len(l))\n    hi = np.clip(np.arange(len(l)) + half + 1, 0, len(l))\n    mean = cumulative[hi] - cumulative[lo]\n    return np.arctan2(mean[:, 0], mean[:, 2])\n\n\ndef compute(parents, offsets, rotations, translations, translated, std, fps):\n    """Per-frame terminator data for a whole clip (arrays over frames)."""\n    rotations = np.asarray(rotations, dtype=np.float64)\n    positions, orientations = kinematics.world_transforms(parents, offsets, rotations, translations, translated)\n    n = len(rotations)\n    pelvis = std[STANDARD_JOINTS.index("pelvis")]\n    theta = headings(positions, std[STANDARD_JOINTS.index("left_hip")], std[STANDARD_JOINTS.index("right_hip")], fps)\n    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]\n    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])\n    world = positions[:, std]\n    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])\n    before, after, span = _neighbours(n)\n    rate = (fps / span)[:, None, None]\n    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)\n\n    canonical = quaternion.canonical(rotations)\n    local_rotations = canonical[:, std]\n    pelvis_s = STANDARD_JOINTS.index("pelvis")\n    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))\n    local_rotations[:, pelvis_s] = pelvis_local\n    angular = _rotvec(quaternion.multiply(quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std])) * rate\n    pelvis_world = _rotvec(quaternion.multiply(orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])))\n    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])\n\n    configuration = canonical.copy()\n    configuration[:, pelvis] = pelvis_local\n    ancestor = parents[pelvis]\n    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame\n        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)\n        ancestor = parents[ancestor]\n\n    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}\n    features = np.concatenate(\n        [local_positions[:, [pelvis_s], 1]]\n        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]\n        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES], axis=1)\n    return {\n        "heading": theta, "pelvis": positions[:, pelvis], "pelvis_height": positions[:, pelvis, 1],\n        "positions": local_positions, "rotations": local_rotations, "velocities": local_velocities,\n        "angular_velocities": angular, "configuration": configuration, "features": features,\n    }\n\n\ndef windows(n_frames, fps, window_s, stride_s):\n    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every stride_s."""\n    length = int(round(window_s * fps)) + 1\n    stride = max(1, int(round(stride_s * fps)))\n    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride\n\n\ndef net_motion(terms, first, last):\n    """Net pelvis translation (in the first frame\'s heading frame) and heading change of frames first..last."""\n    theta = terms["heading"]\n    h_inv = quaternion.conjugate(_about_y(theta[first]))\n    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])\n    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))\n    return translation, turn, _about_y(turn)\n',
            'modb_kernel.transitions': '"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and the\npart of it a chain can keep moving and steering in: the largest strongly connected component (as in\nmotion graphs) that holds turns both ways.\n\nOutside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a\ncomponent it cannot leave that never turns (in Bandai dataset 2, the runs: from a run\'s end only runs\npass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to the\nsteerable component keeps every chain where it can face its next goal.\n\nThe edge test is select_next_snippets\' level 0, computed for all pairs at once: the same search box\naround the end\'s features, the same per-joint ratio (position by the norm, rotation angle, velocities)\nwith the same float4 arithmetic, and the same rule against replaying the previous snippet\'s frames.\nNeeds scipy (the server: Debian\'s python3-scipy) for the box search and the components.\n"""\nimport numpy as np\n\nfrom . import quaternion\n\nBOX_MARGIN = 1e-4  # match_box\'s margin: terminators store float4, features float8\n\n\nclass Terminators:\n    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19, 4)\n    as stored (float4), and features (n, 25)."""\n\n    def __init__(self, positions, rotations, velocities, angular_velocities, features):\n        n = len(features)\n        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)\n        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)\n        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)\n        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)\n\n\ndef _norm(a, b, norm):\n    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens\n    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))\n\n\ndef _joint_terms(term, src, dst, plan, j):\n    """Joint j\'s continuity terms for pairs (end terminator src[k], begin terminator dst[k]): (difference,\n    threshold) for the rotation angle, the position (the plan\'s norm) and, with velocity terms, the\n    velocity and angular velocity."""\n    yield quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]), plan["angle_threshold"][j]\n    yield _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]), plan["position_threshold"][j]\n    if plan["velocity_terms"]:\n        yield _norm(term.velocities[src, j], term.velocities[dst, j], "l2"), plan["velocity_threshold"][j]\n        yield (_norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),\n               plan["angular_velocity_threshold"][j])\n\n\ndef _within(term, src, dst, plan):\n    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio is at\n    most 1. Joint by joint, the tightest first, so most pairs are dropped after one or two joints."""\n    keep = np.ones(len(src), dtype=bool)\n    order = sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j])\n    for j in order:\n        s, d = src[keep], dst[keep]\n        ok = np.ones(len(s), dtype=bool)\n        for difference, threshold in _joint_terms(term, s, d, plan, j):\n            ok &= difference <= threshold\n        keep[np.flatnonzero(keep)[~ok]] = False\n    return keep\n\n\ndef ratios(term, src, dst, plan):\n    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest over the\n    plan\'s joints and terms of difference / threshold (select_next_snippets\' continuity_ratio)."""\n    ratio = np.zeros(len(src))\n    for j in plan["joints"]:\n        for difference, threshold in _joint_terms(term, src, dst, plan, j):\n            ratio = np.maximum(ratio, difference / threshold)\n    return ratio\n\n\ndef edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):\n    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets given by\n    their begin and end terminator rows in `term`, their pose/rate group, clip (and version, mirror: one key)\n    and window. progress(done) is called after each chunk of sources."""\n    from scipy.spatial import cKDTree\n\n    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN\n    out_src, out_dst, out_ratio = [], [], []\n    done = 0\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        tree = cKDTree(term.features[begin[members]] / half)\n        for lo in range(0, len(members), chunk):\n            sources = members[lo:lo + chunk]\n            done += len(sources)\n            near = tree.query_ball_point(term.features[end[sources]] / half, r=1.0, p=np.inf)\n            counts = np.fromiter((len(c) for c in near), dtype=np.int64, count=len(near))\n            if not counts.sum():\n                continue  # (progress is reported with the next chunk that has candidates)\n            s = np.repeat(sources, counts)\n            d = members[np.concatenate([np.asarray(c, dtype=np.int64) for c in near if len(c)])]\n            # No replay of the previous snippet\'s frames (its last frame, the seam, aside).\n            overlap = ((clip[s] == clip[d]) & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)\n                       & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1))\n            s, d = s[~overlap], d[~overlap]\n            keep = _within(term, end[s], begin[d], plan)\n            out_src.append(s[keep])\n            out_dst.append(d[keep])\n            out_ratio.append(ratios(term, end[s[keep]], begin[d[keep]], plan))\n            if progress:\n                progress(done)\n    if not out_src:\n        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)\n    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)\n\n\ndef steerable(n, src, dst, group, turn, min_turn):\n    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate group\n    among those (of more than one snippet) whose snippets include turns of at least min_turn radians each\n    way (`turn`: the heading change where each one leads). A chain in it can always move on, and can face\n    any goal. (The largest only, as in motion graphs: on Bandai dataset 2, adding the active walks\'\n    component to the slow walks\' made right-angle courses worse: README "Transition graphs".)"""\n    from scipy.sparse import coo_matrix\n    from scipy.sparse.csgraph import connected_components\n\n    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()\n    _, label = connected_components(graph, directed=True, connection="strong")\n    turn = np.asarray(turn, dtype=np.float64)\n    size = np.bincount(label, minlength=label.max() + 1)\n    left = np.zeros(len(size), dtype=bool)\n    right = np.zeros(len(size), dtype=bool)\n    np.logical_or.at(left, label, turn >= min_turn)\n    np.logical_or.at(right, label, turn <= -min_turn)\n    eligible = (size > 1) & left & right\n    keep = np.zeros(n, dtype=bool)\n    for g in np.unique(group):\n        members = np.flatnonzero(group == g)\n        candidates = np.unique(label[members][eligible[label[members]]])\n        if len(candidates):\n            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True\n    return keep\n',
            'modb_kernel.validate': '"""Checks the database applies to stored frames (used by CHECK constraints)."""\nimport numpy as np\n\n\ndef unit_quaternions_ok(rotations, tolerance):\n    """True when every trailing 4-vector has unit length within `tolerance` and w >= 0."""\n    try:\n        q = np.asarray(rotations, dtype=np.float64)\n    except (TypeError, ValueError):  # NULL elements arrive as None\n        return False\n    if q.size == 0 or q.shape[-1] != 4 or not np.all(np.isfinite(q)):\n        return False\n    q = q.reshape(-1, 4)\n    return bool(np.all(np.abs(np.linalg.norm(q, axis=1) - 1.0) <= tolerance) and np.all(q[:, 0] >= 0.0))\n\n\ndef finite_ok(values):\n    """True when the (nested) array has no NULL (None), NaN or infinite element."""\n    try:\n        a = np.asarray(values, dtype=np.float64)\n    except (TypeError, ValueError):\n        return False\n    return bool(np.all(np.isfinite(a)))\n',}
        package = 'modb_kernel_0_7_0'
        def find_spec(self, name, path=None, target=None):
            key = "modb_kernel" + name[len(self.package):] if name.split(".")[0] == self.package else None
            if key not in self.sources:
                return None
            return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))
        def create_module(self, spec):
            return None
        def exec_module(self, module):
            key = "modb_kernel" + module.__name__[len(self.package):]
            exec(compile(self.sources[key], "<modb 0.7.0>/" + key.replace(".", "/") + ".py", "exec"),
                 module.__dict__)
    if not any(getattr(f, "package", None) == 'modb_kernel_0_7_0' for f in sys.meta_path):
        sys.meta_path.insert(0, EmbeddedKernel())
    kernel = importlib.import_module('modb_kernel_0_7_0')
    for module in EmbeddedKernel.sources:
        if module != "modb_kernel":
            importlib.import_module('modb_kernel_0_7_0' + module[len("modb_kernel"):])
    GD['modb_kernel 0.7.0'] = kernel
import json
import numpy as np

T = kernel.transitions
TRANSITION_SLACK = 1e-9
if not name:
    plpy.error("a transition graph needs a name")
if min_turn_degrees is None or not 0 <= min_turn_degrees <= 180:
    plpy.error(f"min_turn_degrees must be between 0 and 180, got {min_turn_degrees}")
plan = plpy.execute(plpy.prepare(
    """SELECT to_jsonb(p) - 'box_half_width' AS shown, modb.transition_key(p) AS transition_key, p.*
         FROM modb.match_plan($1) p""", ["text"]), [profile])[0]
collections = None
if collection is not None:
    collections = plpy.execute(plpy.prepare("SELECT modb.collection_subtree($1) AS ids", ["text"]), [collection])[0]["ids"]
    if not collections:
        plpy.error(f'no collection "{collection}"', hint="modb.collection_path(id) names the stored ones")
snippets = plpy.execute(plpy.prepare(
    """SELECT s.id, s.begin_terminator, s.end_terminator, s.pose_key || '@' || s.fps AS grp, s.future_heading,
              s.clip_id || '/' || s.version || '/' || s.mirrored AS clip, s.first_frame, s.n_frames,
              s.net_translation[1] AS net_x, s.net_translation[3] AS net_z, s.net_heading, (s.n_frames - 1) / s.fps AS duration
         FROM modb.snippets s WHERE $1::bigint[] IS NULL OR s.collection_id = ANY ($1) ORDER BY s.id""",
    ["bigint[]"]), [collections])
n = len(snippets)
if n == 0:
    plpy.error("no snippets to build a graph from" + (f' in collection "{collection}"' if collection else ""),
               hint="`modb load` builds snippets")
plpy.notice(f"modb: transition graph \"{name}\": reading the terminators of {n} snippets")
column = lambda key: [r[key] for r in snippets]
terminators = plpy.execute(plpy.prepare(  # those of the snippets just read, each once
    """SELECT t.id, t.positions, t.rotations, t.velocities, t.angular_velocities,
              (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i) FROM generate_series(1, cube_dim(t.features)) i) AS features
         FROM modb.terminators t WHERE t.id = ANY ($1)""", ["bigint[]"]),
    [sorted(set(column("begin_terminator")) | set(column("end_terminator")))])
row_of = {r["id"]: i for i, r in enumerate(terminators)}
term = T.Terminators(*([r[c] for r in terminators] for c in
                       ("positions", "rotations", "velocities", "angular_velocities", "features")))
keys = lambda values: np.unique(values, return_inverse=True)[1]
begin = np.array([row_of[t] for t in column("begin_terminator")])
end = np.array([row_of[t] for t in column("end_terminator")])
group, clip = keys(column("grp")), keys(column("clip"))
first_frame, n_frames = np.array(column("first_frame")), np.array(column("n_frames"))
# A hair looser than level 0, so the stored transitions hold every pair the SQL test passes (numpy and
# SQL round differently); selection applies the exact test again.
thresholds = {k: np.array(plan[k], dtype=np.float64) * (1 + TRANSITION_SLACK) for k in
              ("position_threshold", "angle_threshold", "velocity_threshold", "angular_velocity_threshold")}
spec = dict(thresholds, joints=list(plan["joints"]), norm=plan["norm"], velocity_terms=plan["velocity_terms"],
            box_half_width=plan["box_half_width"])
src, dst, ratio = T.edges(term, begin, end, group, clip, first_frame, n_frames, spec,
                   progress=lambda done: plpy.notice(f"modb: transition graph \"{name}\": {done}/{n} snippets"))
turn = np.array([np.nan if t is None else t for t in column("future_heading")], dtype=np.float64)
keep = T.steerable(n, src, dst, group, np.nan_to_num(turn), np.radians(min_turn_degrees))
ids = np.array(column("id"), dtype=np.int64)
out_degree = np.bincount(src, minlength=n)
inside = keep[src] & keep[dst]
# The cost-to-go among the kept snippets (modb_kernel/cost_to_go.py), priced beyond its grid at their median speed.
C = kernel.cost_to_go
kept = np.flatnonzero(keep)
position = np.full(n, -1)
position[kept] = np.arange(len(kept))
net_x, net_z, heading, duration = (np.array(column(c), dtype=np.float64)[kept] for c in ("net_x", "net_z", "net_heading", "duration"))
grid = C.Grid(speed=max(float(np.median(np.hypot(net_x, net_z) / duration)), C.MIN_SPEED))
plpy.notice(f"modb: transition graph \"{name}\": cost-to-go of {len(kept)} snippets on {grid.angles} x {grid.rings} goal positions")
seconds_per_ratio = (plan["continuity_weight"] or 0) / grid.speed  # the selection's price of a rough seam
seam = ratio[inside] * seconds_per_ratio
costs, iterations, change = C.cost_to_go(
    grid, net_x, net_z, heading, duration, position[src[inside]], position[dst[inside]], seam,
    progress=lambda i, c: i % 10 or plpy.notice(f"modb: transition graph \"{name}\": cost-to-go iteration {i}, largest change {c:.3f} s"))
data = {"profile": profile, "collection": collection, "min_turn_degrees": min_turn_degrees,
        "plan": json.loads(plan["shown"]),
        "snippets": n, "edges": int(len(src)), "kept": int(keep.sum()),
        "dead_ends": int((out_degree == 0).sum()),
        "edges_within_kept": int(inside.sum()), "transition_key": json.loads(plan["transition_key"]),
        "cost_to_go": dict(grid.as_json(), seconds_per_ratio=seconds_per_ratio, iterations=iterations,
                           last_change=change)}
plpy.execute(plpy.prepare("DELETE FROM modb.graphs WHERE name = $1 AND kind = 'transitions'", ["text"]), [name])
graph_id = plpy.execute(plpy.prepare(
    "INSERT INTO modb.graphs (name, kind, data) VALUES ($1, 'transitions', $2::jsonb) RETURNING id",
    ["text", "text"]), [name, json.dumps(data)])[0]["id"]
plpy.execute(plpy.prepare(
    "INSERT INTO modb.graph_snippets (graph_id, snippet_id) SELECT $1, unnest($2::bigint[])", ["bigint", "bigint[]"]),
    [graph_id, ids[keep].tolist()])
plpy.execute(plpy.prepare(  # one row per kept snippet: its successors, and row k of the costs for the k-th
    """INSERT INTO modb.graph_transitions (graph_id, from_snippet, to_snippets, cost_to_go)
       SELECT $1, e.f, e.t, $5[(k.i - 1) * $6 + 1 : k.i * $6]
         FROM (SELECT f, array_agg(t ORDER BY t) AS t FROM unnest($2::bigint[], $3::bigint[]) AS e(f, t) GROUP BY f) e
         JOIN unnest($4::bigint[]) WITH ORDINALITY AS k(id, i) ON k.id = e.f""",
    ["bigint", "bigint[]", "bigint[]", "bigint[]", "real[]", "int"]),
    [graph_id, ids[src[inside]].tolist(), ids[dst[inside]].tolist(), ids[kept].tolist(), costs.ravel().tolist(),
     grid.angles * grid.rings])
plpy.notice(f"modb: transition graph \"{name}\": kept {data['kept']} of {n} snippets "
            f"({data['edges']} transitions, {data['dead_ends']} snippets with none); "
            f"cost-to-go after {iterations} iterations (last change {change:.3f} s)")
return graph_id
$py$;
COMMENT ON FUNCTION modb.build_transition_graph(text, text, text, float8) IS
    'Builds (or rebuilds) the transition graph "name" over the snippets (of the collection): edges are relaxation level 0 of the profile; a snippet is kept when it lies in the largest strongly connected component (per skeleton and rate) among those holding turns of at least min_turn_degrees each way (where snippets lead: future_heading), so a chain restricted to it (SET modb.graph) never runs into a dead end and can face any goal; stores each kept snippet''s level-0 successors and its cost-to-go (seconds to goals around its end through the graph); returns the modb.graphs id. Rebuild after loading';

-- 75_graphs_transitions.sql
-- A transition graph's level-0 transitions, stored. From a kept snippet, select_next_snippet reads its
-- successors here (one index lookup, then the exact check of a few dozen rows) instead of searching the
-- feature box (which admits hundreds to thousands of candidates in dense data, each checked exactly).
-- Valid only for the continuity settings the graph was built with: modb.transition_key says which.

CREATE TABLE modb.graph_transitions (
    graph_id     bigint NOT NULL,
    from_snippet bigint NOT NULL,
    to_snippets  bigint[] NOT NULL,
    cost_to_go   real[],
    PRIMARY KEY (graph_id, from_snippet),
    FOREIGN KEY (graph_id, from_snippet) REFERENCES modb.graph_snippets ON DELETE CASCADE
);
COMMENT ON TABLE modb.graph_transitions IS
    'For each snippet a transition graph keeps: the kept snippets that may follow it at relaxation level 0 (a superset by a hair: the exact test runs again at selection). One row per snippet, not per transition: a tenth of the size';
SELECT pg_catalog.pg_extension_config_dump('modb.graph_transitions', '');

CREATE OR REPLACE FUNCTION modb.transition_key(plan modb.match_plan)
RETURNS jsonb
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- The settings that decide which transitions pass level 0; the objective's weights do not.
RETURN jsonb_build_object('joints', (plan).joints, 'norm', (plan).norm, 'velocity_terms', (plan).velocity_terms,
                          'position_threshold', (plan).position_threshold, 'angle_threshold', (plan).angle_threshold,
                          'velocity_threshold', (plan).velocity_threshold,
                          'angular_velocity_threshold', (plan).angular_velocity_threshold);
COMMENT ON FUNCTION modb.transition_key(modb.match_plan) IS
    'What a plan''s level-0 test depends on (joints, norm, velocity terms, thresholds): a graph''s stored transitions serve the plans with its key';

-- 75_graphs_transitions_cost_to_go.sql
-- Reading a transition graph's cost-to-go (modb_kernel/cost_to_go.py says what it is and how it is
-- computed): the bilinear read in (angle, log radius) of the kernel's `interpolation`, in SQL, so that
-- select_next_snippet ranks candidates by it inside its one query. Upgrades include this file (after adding
-- the column).

COMMENT ON COLUMN modb.graph_transitions.cost_to_go IS
    'Seconds from this snippet''s end until a chain through the graph reaches a goal, for goals on the polar grid graphs.data->''cost_to_go'' describes (read with modb.cost_to_go); NULL in graphs built before 0.6.0';

CREATE OR REPLACE FUNCTION modb.cost_to_go(costs real[], goal float8[], grid jsonb)
RETURNS float8
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN (SELECT CASE WHEN r <= inner_radius THEN 0
                    ELSE (1 - wa) * ((1 - wj) * costs[a0 * rings + j0 + 1] + wj * costs[a0 * rings + j0 + 2])
                         + wa * ((1 - wj) * costs[a1 * rings + j0 + 1] + wj * costs[a1 * rings + j0 + 2])
                         + greatest(r - outer_radius, 0) / speed END
          FROM (SELECT r, inner_radius, outer_radius, speed, rings,
                       angle - floor(angle) AS wa, floor(angle)::int % angles AS a0, (floor(angle)::int + 1) % angles AS a1,
                       ring - floor(ring) AS wj, floor(ring)::int AS j0
                  FROM (SELECT r, inner_radius, outer_radius, speed, rings, angles,
                               least(greatest(ln(greatest(r, 1e-9) / inner_radius) / ln(outer_radius / inner_radius) * (rings - 1), 0),
                                     rings - 1 - 1e-9) AS ring,
                               (theta - 2 * pi() * floor(theta / (2 * pi()))) / (2 * pi() / angles) AS angle
                          FROM (SELECT sqrt(goal[1] ^ 2 + goal[array_length(goal, 1)] ^ 2) AS r,
                                       atan2(goal[1], goal[array_length(goal, 1)]) AS theta,
                                       (grid->>'inner_radius')::float8 AS inner_radius, (grid->>'outer_radius')::float8 AS outer_radius,
                                       (grid->>'speed')::float8 AS speed, (grid->>'rings')::int AS rings,
                                       (grid->>'angles')::int AS angles) given) ring) cell);
COMMENT ON FUNCTION modb.cost_to_go(real[], float8[], jsonb) IS
    'Seconds until a chain through a transition graph reaches goal ({x, z} or {x, y, z}, metres in the heading frame at a snippet''s end), read from that snippet''s cost_to_go (modb.graph_transitions) on the grid graphs.data->''cost_to_go'' describes';

-- 76_select.sql
-- select_next_snippet: continuity (WHERE) and objective (ORDER BY) as one query the planner sees whole.
-- The objective (modb.approach_cost): the nearer of where the candidate ends and where it leads
-- (future_translation: itself and up to two play-on snippets) measured against the aim point (the goal,
-- or the point lookahead_distance along the way to a farther one, so that a far goal does not favour the
-- fastest gait, which cannot turn), plus the profile's
-- continuity_weight x its continuity ratio, so a smoother candidate wins unless another serves the goal
-- clearly better. With a transition graph's stored transitions, level 0 ranks by the graph's cost-to-go
-- instead: the time to the goal through the candidate, however many snippets the turn takes (graphs
-- built before 0.6.0 have none: there graph_lookahead scores each candidate also by the best of its
-- successors placed after it). CREATE OR REPLACE: upgrades include this file.
-- LANGUAGE sql, STABLE, not STRICT, one SELECT: inlined into the caller's plan, so EXPLAIN shows the
-- GiST index scan on snippets.begin_features with the profile's box as its Index Cond.

CREATE OR REPLACE FUNCTION modb.select_next_snippets(prev_snippet bigint, target float8[], k int,
                                          profile text DEFAULT 'default', collection text DEFAULT NULL,
                                          exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
WITH cfg AS MATERIALIZED (
    SELECT plan, checked, collections, modb.aim_point(target, (plan).lookahead_distance) AS aim,
           -- prev's level-0 successors are stored (modb.graph_transitions) for these continuity settings
           EXISTS (SELECT FROM modb.graphs g JOIN modb.graph_transitions e ON e.graph_id = g.id
                    WHERE g.id = (plan).graph_id AND e.from_snippet = prev_snippet
                      AND g.data->'transition_key' = modb.transition_key(plan)) AS stored,
           -- the grid of the graph's cost-to-go, when it has one and the plan ranks by it
           (SELECT g.data->'cost_to_go' FROM modb.graphs g WHERE g.id = (plan).graph_id AND (plan).graph_cost_to_go) AS cost_grid
      FROM (SELECT modb.match_plan(profile) AS plan, modb.check_request(prev_snippet, target, k, collection) AS checked,
                   CASE WHEN collection IS NULL THEN NULL ELSE modb.collection_subtree(collection) END AS collections) resolved
), prev AS MATERIALIZED (
    SELECT t AS term, t.features, s.pose_key, s.fps
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator
     WHERE s.id = prev_snippet
       AND (SELECT checked FROM cfg)  -- every path reads prev or cfg first: bad requests always raise
), candidates AS NOT MATERIALIZED (
    -- The filters every level shares: same skeleton poses and rate, the collection, the transition graph
    -- (when the plan names one: its snippets never lead into a dead end), and no replay of a
    -- frame the previous snippet or a recent one covered (its first frame, the seam, aside).
    SELECT s.*
      FROM modb.snippets s
     WHERE (collection IS NULL OR s.collection_id = ANY ((SELECT collections FROM cfg)::bigint[]))
       AND ((SELECT (plan).graph_id FROM cfg) IS NULL
            OR EXISTS (SELECT FROM modb.graph_snippets g
                        WHERE g.graph_id = (SELECT (plan).graph_id FROM cfg) AND g.snippet_id = s.id))
       AND NOT EXISTS (SELECT FROM modb.snippets x
                        WHERE (x.id = ANY (exclude) OR x.id = prev_snippet)
                          AND x.clip_id = s.clip_id AND x.version = s.version
                          AND x.mirrored = s.mirrored
                          AND x.first_frame + 1 <= s.first_frame + s.n_frames - 1
                          AND s.first_frame + 1 <= x.first_frame + x.n_frames - 1)
)
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)) AS proximity,
        0, NULL::float8, c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c
  WHERE prev_snippet IS NULL AND (SELECT checked FROM cfg)
  ORDER BY 7, 1 LIMIT k)
-- Relaxation levels 0-3: every threshold (and the box) scaled by 2^level; a row reports the lowest
-- level it satisfies. Level 4, the last: the nearest start configuration (feature distance), any ratio.
-- Level 0 from a graph's stored transitions when it has them for prev and these settings, else the box.
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames, o.objective, 0, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM modb.graph_transitions e CROSS JOIN LATERAL unnest(e.to_snippets) AS next(id)
   JOIN candidates c ON c.id = next.id
   JOIN modb.graph_transitions ce ON ce.graph_id = e.graph_id AND ce.from_snippet = c.id  -- the candidate's own row
   JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  -- graph_lookahead (graphs without a cost-to-go): the best of this candidate's successors in the graph,
  -- placed after it, may stand in for where it leads (a turn that only the next snippet completes);
  -- least() ignores the NULL without it.
  CROSS JOIN LATERAL (
      SELECT min(modb.approach_cost(n2.net_translation, n2.future_translation, n2.future_heading,
                                    modb.aim_point(modb.world_to_local(c.net_translation, c.net_heading, target), (cfg.plan).lookahead_distance),
                                    (cfg.plan).heading_weight)) AS cost
        FROM unnest(ce.to_snippets) AS next2(id) JOIN modb.snippets n2 ON n2.id = next2.id
       WHERE (cfg.plan).graph_lookahead AND cfg.cost_grid IS NULL) two
  -- The objective in metres: with the graph's cost-to-go, the seconds to the goal through this candidate
  -- (its own duration, then the cost-to-go from its end) at the graph's median speed; else as the box levels.
  CROSS JOIN LATERAL (
      SELECT CASE WHEN cfg.cost_grid IS NOT NULL
                  THEN (cfg.cost_grid->>'speed')::float8
                       * ((c.n_frames - 1) / c.fps
                          + modb.cost_to_go(ce.cost_to_go, modb.world_to_local(c.net_translation, c.net_heading, target), cfg.cost_grid))
                  ELSE least(modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, cfg.aim, (cfg.plan).heading_weight),
                             two.cost) END AS objective) o
  WHERE (SELECT stored FROM cfg)
    AND e.graph_id = (SELECT (plan).graph_id FROM cfg) AND e.from_snippet = prev_snippet
    AND r.ratio <= 1.0
  ORDER BY o.objective + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 0, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE NOT (SELECT stored FROM cfg)
    AND c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 1.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 1.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 1, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 2.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 2.0 AND r.ratio > 1.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 2, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 4.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 4.0 AND r.ratio > 2.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)), 3, r.ratio,
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg  -- as columns, not sub-selects, so continuity_ratio is inlined
  CROSS JOIN LATERAL (SELECT modb.continuity_ratio(prev.term, b, cfg.plan) AS ratio) r
  WHERE c.begin_features <@ (SELECT modb.match_box(prev.features, cfg.plan, 8.0) FROM prev, cfg)
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND r.ratio <= 8.0 AND r.ratio > 4.0
  ORDER BY modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg))
           + (SELECT (plan).continuity_weight FROM cfg) * r.ratio, 1 LIMIT k)
UNION ALL
(SELECT c.id, c.clip_id, c.version, c.mirrored, c.first_frame, c.n_frames,
        modb.approach_cost(c.net_translation, c.future_translation, c.future_heading, (SELECT aim FROM cfg), (SELECT (plan).heading_weight FROM cfg)),
        4, modb.continuity_ratio(prev.term, b, cfg.plan),
        c.net_translation, c.net_rotation, c.net_heading
   FROM candidates c JOIN modb.terminators b ON b.id = c.begin_terminator
  CROSS JOIN prev CROSS JOIN cfg
  WHERE prev_snippet IS NOT NULL
    AND c.pose_key = (SELECT pose_key FROM prev) AND c.fps = (SELECT fps FROM prev)
    AND modb.continuity_ratio(prev.term, b, cfg.plan) > 8
  ORDER BY c.begin_features <-> (SELECT features FROM prev), c.id LIMIT k)
LIMIT k
$$;
COMMENT ON FUNCTION modb.select_next_snippets(bigint, float8[], int, text, text, bigint[]) IS
    'The k best continuations of prev_snippet toward target ({x, z} or {x, y, z}, metres, in the avatar''s heading frame at its end), ordered by relaxation level, then proximity (from the nearer of where the snippet ends and where it leads to the aim point: the target, or the point the profile''s lookahead_distance along the way to it) + continuity_weight x continuity (from a graph snippet at level 0: with the graph''s cost-to-go, the seconds to the goal through the candidate x the graph''s median speed; else with graph_lookahead, the proximity of the candidate or of its best successor, whichever is nearer); prev_snippet NULL: the snippets that best serve the target';

CREATE OR REPLACE FUNCTION modb.select_next_snippet(prev_snippet bigint, target float8[], profile text DEFAULT 'default',
                                         collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT * FROM modb.select_next_snippets(prev_snippet, target, 1, profile, collection, exclude)
$$;
COMMENT ON FUNCTION modb.select_next_snippet(bigint, float8[], text, text, bigint[]) IS
    'The snippet that continues prev_snippet smoothly (the profile''s thresholds, relaxed in steps when nothing passes) and brings the avatar nearest to target ({x, z} or {x, y, z} metres in its heading frame at the end of prev_snippet; x left, z forward). prev_snippet NULL: the snippet that best serves the target. exclude: recently played snippets, whose frames are not replayed';

CREATE OR REPLACE FUNCTION modb.world_to_local(origin float8[], heading float8, target_world float8[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- Heading theta faces (sin theta, 0, cos theta); the character's left is (cos theta, 0, -sin theta).
RETURN CASE WHEN array_length(target_world, 1) = 3
    THEN ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[3] - origin[3]) * sin(heading),
               target_world[2] - origin[2],
               (target_world[1] - origin[1]) * sin(heading) + (target_world[3] - origin[3]) * cos(heading)]
    ELSE ARRAY[(target_world[1] - origin[1]) * cos(heading) - (target_world[2] - origin[3]) * sin(heading),
               (target_world[1] - origin[1]) * sin(heading) + (target_world[2] - origin[3]) * cos(heading)] END;
COMMENT ON FUNCTION modb.world_to_local(float8[], float8, float8[]) IS
    'A world target ({x, z} on the ground or {x, y, z}) in the heading frame of a character at origin {x, y, z} with heading theta';

CREATE OR REPLACE FUNCTION modb.select_next_snippet_world(prev_snippet bigint, "position" float8[], heading float8,
                                               target_world float8[], profile text DEFAULT 'default',
                                               collection text DEFAULT NULL, exclude bigint[] DEFAULT NULL)
RETURNS TABLE (snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int, n_frames int,
               proximity float8, relax_level int, continuity float8, net_translation float8[],
               net_rotation float8[], net_heading float8)
LANGUAGE sql STABLE PARALLEL SAFE
AS $$
SELECT * FROM modb.select_next_snippets(prev_snippet, modb.world_to_local(select_next_snippet_world."position", heading, target_world), 1,
                                         profile, collection, exclude)
$$;
COMMENT ON FUNCTION modb.select_next_snippet_world(bigint, float8[], float8, float8[], text, text, bigint[]) IS
    'select_next_snippet with the goal in world coordinates: the avatar at position {x, y, z} with heading theta (radians, 0 = facing +Z)';

-- 77_candidates.sql
-- How much work a selection did: the candidates select_next_snippet scored for continuity on its way to
-- the relaxation level that answered. Latency follows this count (README "Performance"), and the
-- thresholds, joints and velocity terms move it; the avatar view reports it after every selection.
-- CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.candidates_examined(prev_snippet bigint, relax_level int, profile text DEFAULT 'default')
RETURNS bigint
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
DECLARE
    plan modb.match_plan := modb.match_plan(profile);
    prev record;
    stored int;
    level int;
    total bigint := 0;
    n bigint;
BEGIN
    IF relax_level IS NULL OR relax_level NOT BETWEEN 0 AND 4 THEN
        RAISE EXCEPTION 'relax_level must be 0-4 (select_next_snippet''s relax_level), got %', relax_level;
    END IF;
    IF prev_snippet IS NULL THEN  -- a start ranks every snippet
        RETURN (SELECT count(*) FROM modb.snippets);
    END IF;
    SELECT t.features, s.pose_key, s.fps INTO prev
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = prev_snippet;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no snippet %', prev_snippet USING HINT = 'prev_snippet is a modb.snippets id';
    END IF;
    -- Level 0 from the graph's stored transitions, under the same condition as select_next_snippet.
    SELECT cardinality(e.to_snippets) INTO stored
      FROM modb.graphs g JOIN modb.graph_transitions e ON e.graph_id = g.id
     WHERE g.id = plan.graph_id AND e.from_snippet = prev_snippet
       AND g.data->'transition_key' = modb.transition_key(plan);
    FOR level IN 0 .. relax_level LOOP
        IF level = 0 AND stored IS NOT NULL THEN
            n := stored;
        ELSIF level = 4 THEN  -- the nearest start configuration among every snippet of the same pose and rate
            SELECT count(*) INTO n FROM modb.snippets c WHERE c.pose_key = prev.pose_key AND c.fps = prev.fps;
        ELSE  -- what the GiST box of this level yields
            SELECT count(*) INTO n FROM modb.snippets c
             WHERE c.begin_features <@ modb.match_box(prev.features, plan, 2.0 ^ level)
               AND c.pose_key = prev.pose_key AND c.fps = prev.fps;
        END IF;
        total := total + n;
    END LOOP;
    RETURN total;
END
$$;
COMMENT ON FUNCTION modb.candidates_examined(bigint, int, text) IS
    'The candidates select_next_snippet scored for continuity after prev_snippet, summed over the relaxation levels it tried up to relax_level (the one it answered at): at each level the snippets of the same pose and rate in its search box (level 0 of a transition graph that stores prev''s successors: those; level 4: all), before the collection, graph and exclude filters. Reads this session''s SET modb.<knob> like the selection; prev_snippet NULL: every snippet';

-- 78_synthesize.sql
-- synthesize: a whole chain of snippets toward a queue of world goals, in one recursive query, so any SQL
-- client can synthesize. The Python Avatar (client/modb/avatar.py) follows the same rules step for step;
-- with lead time zero both give the same chain (tested).
--
-- Rules: the avatar stands at a ground point with a heading. A snippet is placed with its first frame on
-- that point and heading; at its end the avatar has moved by net_translation (x, z; in the heading frame)
-- and turned by net_heading. A goal is reached when the pelvis is within arrival_radius of it (on the
-- ground) at a snippet's end; the next choice then serves the next goal, and after the last goal the
-- avatar keeps serving the last one. Snippets whose play ended less than exclude_seconds before the end of
-- the current one are passed as exclude. Time is counted in frames (the chain has one rate), so both
-- paths compare the same integers. When nothing can follow, the chain ends (the Avatar raises NoContinuation
-- there, and modb synth stops the strip and says so). CREATE OR REPLACE: upgrades include this file.

CREATE OR REPLACE FUNCTION modb.local_to_world(origin float8[], heading float8, local_point float8[])
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- The inverse of world_to_local: x left and z forward of a character at origin facing heading.
RETURN CASE WHEN array_length(local_point, 1) = 3
    THEN ARRAY[origin[1] + (local_point[1] * cos(heading) + local_point[3] * sin(heading)),
               origin[2] + local_point[2],
               origin[3] + (local_point[3] * cos(heading) - local_point[1] * sin(heading))]
    ELSE ARRAY[origin[1] + (local_point[1] * cos(heading) + local_point[2] * sin(heading)),
               origin[3] + (local_point[2] * cos(heading) - local_point[1] * sin(heading))] END;
COMMENT ON FUNCTION modb.local_to_world(float8[], float8, float8[]) IS
    'A point given in the heading frame of a character at origin {x, y, z} with heading theta ({x, z} or {x, y, z}; x left, z forward) in world coordinates';

CREATE OR REPLACE FUNCTION modb.synthesis_goal(targets float8[], goal int)
RETURNS float8[]
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
RETURN CASE array_length(targets, 2) WHEN 2 THEN ARRAY[targets[goal][1], targets[goal][2]]
            ELSE ARRAY[targets[goal][1], targets[goal][2], targets[goal][3]] END;
COMMENT ON FUNCTION modb.synthesis_goal(float8[], int) IS
    'Row goal (1-based) of a synthesize targets array, as a {x, z} or {x, y, z} world point';

CREATE OR REPLACE FUNCTION modb.synthesis_step_end(origin float8[], heading float8, net_translation float8[], net_heading float8,
                                        target float8[], arrival_radius float8)
RETURNS TABLE (end_position float8[], end_heading float8, reached boolean)
LANGUAGE sql IMMUTABLE PARALLEL SAFE
AS $$
SELECT w.p, atan2(sin(heading + net_heading), cos(heading + net_heading)),
       sqrt((w.p[1] - target[1]) * (w.p[1] - target[1])
            + (w.p[3] - target[array_length(target, 1)]) * (w.p[3] - target[array_length(target, 1)])) <= arrival_radius
  FROM (SELECT modb.local_to_world(origin, heading, ARRAY[net_translation[1], 0, net_translation[3]]) AS p) w
$$;
COMMENT ON FUNCTION modb.synthesis_step_end(float8[], float8, float8[], float8, float8[], float8) IS
    'Where a snippet placed at origin/heading leaves the avatar (its ground travel and turn), and whether the pelvis is then within arrival_radius of target on the ground';

CREATE OR REPLACE FUNCTION modb.check_synthesis(targets float8[], max_snippets int, start_snippet bigint,
                                     start_position float8[], start_heading float8, profile text,
                                     arrival_radius float8, exclude_seconds float8)
RETURNS boolean
LANGUAGE plpgsql STABLE PARALLEL SAFE
AS $$
BEGIN
    IF targets IS NULL OR array_ndims(targets) IS DISTINCT FROM 2 OR array_length(targets, 2) NOT IN (2, 3)
       OR EXISTS (SELECT FROM unnest(targets) v WHERE v IS NULL OR v = 'NaN' OR v IN ('Infinity', '-Infinity')) THEN
        RAISE EXCEPTION 'targets must be a list of world goals {{x, z}, ...} or {{x, y, z}, ...} in metres, got %',
            coalesce(targets::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF max_snippets IS NULL OR max_snippets < 1 THEN
        RAISE EXCEPTION 'max_snippets must be at least 1, got %', coalesce(max_snippets::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_position IS NULL OR array_ndims(start_position) IS DISTINCT FROM 1 OR array_length(start_position, 1) <> 3
       OR EXISTS (SELECT FROM unnest(start_position) v WHERE v IS NULL OR v = 'NaN' OR v IN ('Infinity', '-Infinity')) THEN
        RAISE EXCEPTION 'start_position must be {x, y, z} in metres, got %', coalesce(start_position::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_heading IS NULL OR start_heading = 'NaN' OR start_heading IN ('Infinity', '-Infinity') THEN
        RAISE EXCEPTION 'start_heading must be a finite angle in radians (0 faces +Z), got %',
            coalesce(start_heading::text, 'NULL') USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF arrival_radius IS NULL OR NOT arrival_radius > 0 OR arrival_radius = 'Infinity' THEN
        RAISE EXCEPTION 'arrival_radius must be a positive number of metres, got %', coalesce(arrival_radius::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF exclude_seconds IS NULL OR NOT exclude_seconds >= 0 OR exclude_seconds = 'Infinity' THEN
        RAISE EXCEPTION 'exclude_seconds must be zero or more, got %', coalesce(exclude_seconds::text, 'NULL')
            USING ERRCODE = 'invalid_parameter_value';
    END IF;
    IF start_snippet IS NOT NULL AND NOT EXISTS (SELECT FROM modb.snippets WHERE id = start_snippet) THEN
        RAISE EXCEPTION 'no snippet %', start_snippet USING ERRCODE = 'invalid_parameter_value',
            HINT = 'start_snippet is a modb.snippets id, or NULL for the snippet that best serves the first goal';
    END IF;
    PERFORM modb.match_plan(profile);  -- an unknown profile fails here even when no selection runs
    RETURN true;
END
$$;
COMMENT ON FUNCTION modb.check_synthesis(float8[], int, bigint, float8[], float8, text, float8, float8) IS
    'Raises a clear error for a synthesize request that cannot be run (bad targets, sizes, start or profile)';

CREATE OR REPLACE FUNCTION modb.synthesize(targets float8[], max_snippets int, start_snippet bigint DEFAULT NULL,
                                start_position float8[] DEFAULT '{0,0,0}', start_heading float8 DEFAULT 0,
                                profile text DEFAULT 'default', collection text DEFAULT NULL,
                                arrival_radius float8 DEFAULT 0.5, exclude_seconds float8 DEFAULT 2)
RETURNS TABLE (step int, snippet_id bigint, clip_id bigint, version int, mirrored boolean, first_frame int,
               n_frames int, fps float8, start_time float8, "position" float8[], heading float8,
               end_position float8[], end_heading float8, goal int, target float8[], reached boolean,
               relax_level int, continuity float8, proximity float8)
LANGUAGE sql STABLE PARALLEL SAFE
-- Each step runs select_next_snippet_world as a function with a generic plan, whose estimate (it keeps the
-- opening branch's full scan) passes jit_above_cost: JIT then compiled for ~9 s per step, against ~0.15 s
-- of work. A SET clause keeps synthesize from being inlined, which gains nothing for one recursive query.
SET jit = off
AS $$
WITH RECURSIVE cfg AS MATERIALIZED (
    SELECT modb.check_synthesis(targets, max_snippets, start_snippet, start_position, start_heading, profile,
                                arrival_radius, exclude_seconds) AS ok,
           array_length(targets, 1) AS n_goals
), opening AS (
    -- The given start snippet, or the one that best serves the first goal.
    SELECT s.id AS snippet_id, NULL::int AS relax_level, NULL::float8 AS continuity, NULL::float8 AS proximity
      FROM modb.snippets s
     WHERE s.id = start_snippet AND (SELECT ok FROM cfg)
    UNION ALL
    SELECT n.snippet_id, n.relax_level, n.continuity, n.proximity
      FROM modb.select_next_snippet_world(NULL, start_position, start_heading, modb.synthesis_goal(targets, 1),
                                          profile, collection) n
     WHERE start_snippet IS NULL AND (SELECT ok FROM cfg)
), chain AS (
    SELECT 0 AS step, s.id AS snippet_id, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, s.fps,
           0 AS start_frame, s.n_frames - 1 AS end_frame, start_position AS "position", start_heading AS heading,
           e.end_position, e.end_heading, 1 AS goal, g.target, e.reached, o.relax_level, o.continuity, o.proximity,
           ARRAY(SELECT s.id WHERE 0 < exclude_seconds * s.fps) AS recent_ids,
           ARRAY(SELECT s.n_frames - 1 WHERE 0 < exclude_seconds * s.fps) AS recent_ends
      FROM opening o
      JOIN modb.snippets s ON s.id = o.snippet_id
     CROSS JOIN LATERAL (SELECT modb.synthesis_goal(targets, 1) AS target) g
     CROSS JOIN LATERAL modb.synthesis_step_end(start_position, start_heading, s.net_translation, s.net_heading,
                                                g.target, arrival_radius) e
    UNION ALL
    SELECT c.step + 1, s.id, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, s.fps,
           c.end_frame, f.end_frame, c.end_position, c.end_heading,
           e.end_position, e.end_heading, g.goal, g.target, e.reached, n.relax_level, n.continuity, n.proximity,
           k.ids, k.ends
      FROM chain c
     CROSS JOIN LATERAL (SELECT CASE WHEN c.reached AND c.goal < (SELECT n_goals FROM cfg) THEN c.goal + 1
                                     ELSE c.goal END AS goal) gi
     CROSS JOIN LATERAL (SELECT gi.goal, modb.synthesis_goal(targets, gi.goal) AS target) g
     CROSS JOIN LATERAL modb.select_next_snippet_world(c.snippet_id, c.end_position, c.end_heading, g.target,
                                                       profile, collection, c.recent_ids) n
      JOIN modb.snippets s ON s.id = n.snippet_id
     CROSS JOIN LATERAL modb.synthesis_step_end(c.end_position, c.end_heading, s.net_translation, s.net_heading,
                                                g.target, arrival_radius) e
     CROSS JOIN LATERAL (SELECT c.end_frame + s.n_frames - 1 AS end_frame) f
     CROSS JOIN LATERAL (  -- the snippets played within exclude_seconds of this one's end (itself included)
         SELECT coalesce(array_agg(r.id), '{}') AS ids, coalesce(array_agg(r.e), '{}') AS ends
           FROM unnest(c.recent_ids || s.id, c.recent_ends || f.end_frame) AS r(id, e)
          WHERE f.end_frame - r.e < exclude_seconds * s.fps) k
     WHERE c.step + 1 < max_snippets
)
SELECT step, snippet_id, clip_id, version, mirrored, first_frame, n_frames, fps, start_frame / fps,
       "position", heading, end_position, end_heading, goal, target, reached, relax_level, continuity, proximity
  FROM chain
 WHERE (SELECT ok FROM cfg)  -- a one-time filter, run first: bad requests raise even when no snippet matches
$$;
COMMENT ON FUNCTION modb.synthesize(float8[], int, bigint, float8[], float8, text, text, float8, float8) IS
    'A chain of up to max_snippets snippets from start_position/start_heading (world metres, radians; 0 faces +Z) through the world goals in targets ({{x, z}, ...} or {{x, y, z}, ...}), in order: one row per snippet with where it is placed, where it ends, the goal it served and whether it reached it (pelvis within arrival_radius on the ground), and its selection (relaxation level, continuity, proximity). Its first frame stands in for the previous snippet''s last; start_time is the time of that frame. The chain ends early when nothing can follow (every candidate excluded)';

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
GRANT INSERT, DELETE ON modb.graph_snippets, modb.graph_transitions TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.build_transition_graph(text, text, text, float8) TO modb_loader;
