"""A brute-force select_next_snippet, written independently of the extension and modb_kernel.

It reads only the stored frames (clip_versions), the skeletons and the profile settings; recomputes
every terminator with its own forward kinematics (scipy rotations), heading, velocities and features
following the definitions in the README; and scores every snippet window against the previous
snippet's end."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

STANDARD = [
    "pelvis",
    "spine",
    "chest",
    "neck",
    "head",
    "left_hip",
    "left_knee",
    "left_ankle",
    "left_toe",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_hip",
    "right_knee",
    "right_ankle",
    "right_toe",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
]
FEATURE_POS = ["head", "left_wrist", "right_wrist", "left_ankle", "right_ankle"]
FEATURE_VEL = ["pelvis", "left_ankle", "right_ankle"]
FEATURE_ROT = ["neck", "head", "left_wrist", "right_wrist"]  # rotation-matrix columns x, y
KNOBS = (
    "joints",
    "norm",
    "position_threshold",
    "angle_threshold",
    "velocity_threshold",
    "angular_velocity_threshold",
    "velocity_terms",
    "heading_weight",
    "continuity_weight",
    "lookahead_distance",
    "graph",
    "graph_lookahead",
    "graph_cost_to_go",
    "annotations",
)


def _rot(q: np.ndarray) -> Rotation:
    q = np.asarray(q, dtype=np.float64)
    # scipy: scalar last
    return Rotation.from_quat(np.concatenate([q[..., 1:], q[..., :1]], axis=-1))


def _wxyz(r: Rotation) -> np.ndarray:
    x = r.as_quat()
    q = np.concatenate([x[..., 3:], x[..., :3]], axis=-1)
    return np.where(q[..., :1] < 0, -q, q)


def _yaw(theta) -> Rotation:
    return Rotation.from_rotvec(np.outer(theta, [0.0, 1.0, 0.0]))


@dataclass
class ClipTerms:
    pos: np.ndarray  # (F, 19, 3) local
    rot: np.ndarray  # (F, 19, 4)
    vel: np.ndarray
    angvel: np.ndarray
    feat: np.ndarray  # (F, 49)
    pelvis: np.ndarray  # (F, 3) world
    heading: np.ndarray


def world_transforms(
    parents, offsets, translated, rotations, translations
) -> tuple[np.ndarray, list[Rotation]]:
    """Forward kinematics with scipy: world positions (F, J, 3) and orientations (one Rotation per
    joint)."""
    n, J = rotations.shape[:2]
    local = np.tile(np.asarray(offsets, dtype=np.float64), (n, 1, 1))
    if len(translated):
        local[:, list(translated)] = np.asarray(translations, dtype=np.float64)
    world_p = np.zeros((n, J, 3))
    world_r: list[Rotation] = [None] * J
    for k, p in enumerate(parents):
        r = _rot(rotations[:, k])
        if p < 0:
            world_p[:, k], world_r[k] = local[:, k], r
        else:
            world_p[:, k] = world_p[:, p] + world_r[p].apply(local[:, k])
            world_r[k] = world_r[p] * r
    return world_p, world_r


def motion_world(motion) -> tuple[np.ndarray, list[Rotation]]:
    """world_transforms of a Motion's own arrays (skeleton, rotations, translations)."""
    sk = motion.skeleton
    return world_transforms(
        sk.parents,
        [j.offset for j in sk.joints],
        sk.translated,
        motion.rotations,
        motion.translations,
    )


def clip_terms(
    hierarchy: dict, joint_map: dict, rotations: np.ndarray, translations, fps: float
) -> ClipTerms:
    joints = hierarchy["joints"]
    names = [j["name"] for j in joints]
    n = rotations.shape[0]
    world_p, world_r = world_transforms(
        [j["parent"] for j in joints],
        [j["offset"] for j in joints],
        hierarchy["translated"],
        rotations,
        translations,
    )
    idx = [names.index(joint_map[s]) for s in STANDARD]
    pel = idx[0]
    lhip, rhip = idx[STANDARD.index("left_hip")], idx[STANDARD.index("right_hip")]
    axis = world_p[:, lhip] - world_p[:, rhip]
    fwd = np.stack([-axis[:, 2], np.zeros(n), axis[:, 0]], axis=1)
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    half = int(round(0.25 * fps))
    mean = np.array([fwd[max(0, t - half) : min(n, t + half + 1)].sum(axis=0) for t in range(n)])
    theta = np.arctan2(mean[:, 0], mean[:, 2])
    to_local = _yaw(theta).inv()
    ground = world_p[:, pel] * [1, 0, 1]
    pos = np.stack([to_local.apply(world_p[:, k] - ground) for k in idx], axis=1)
    before = np.maximum(np.arange(n) - 1, 0)
    after = np.minimum(np.arange(n) + 1, n - 1)
    dt = np.maximum(after - before, 1) / fps
    vel = np.stack(
        [to_local.apply((world_p[after, k] - world_p[before, k]) / dt[:, None]) for k in idx],
        axis=1,
    )
    rot = np.stack(
        [_wxyz(to_local * world_r[pel])] + [_wxyz(_rot(rotations[:, k])) for k in idx[1:]], axis=1
    )
    pelvis_w = (world_r[pel][after] * world_r[pel][before].inv()).as_rotvec() / dt[:, None]
    angvel = [to_local.apply(pelvis_w)]
    for k in idx[1:]:
        r = _rot(rotations[:, k])
        angvel.append((r[before].inv() * r[after]).as_rotvec() / dt[:, None])
    angvel = np.stack(angvel, axis=1)
    s = {name: i for i, name in enumerate(STANDARD)}
    matrices = {j: _rot(rot[:, s[j]]).as_matrix() for j in FEATURE_ROT}
    feat = np.concatenate(
        [pos[:, [0], 1]]
        + [pos[:, s[j]] for j in FEATURE_POS]
        + [vel[:, s[j]] for j in FEATURE_VEL]
        + [matrices[j][:, :, column] for j in FEATURE_ROT for column in (0, 1)],
        axis=1,
    )
    return ClipTerms(pos, rot, vel, angvel, feat, world_p[:, pel], theta)


def resolve_profile(settings: dict, knobs: dict) -> dict:
    settings = dict(settings)
    for knob, value in knobs.items():
        if knob == "joints":
            settings[knob] = value.replace(" ", "").split(",")
        elif knob == "norm":
            settings[knob] = value.lower()
        elif knob in ("velocity_terms", "graph_lookahead", "graph_cost_to_go"):
            settings[knob] = value.lower() in ("on", "true", "1", "yes")
        elif knob.endswith("threshold"):
            settings[knob] = {"default": float(value)}
        else:
            settings[knob] = float(value)

    def per_joint(spec, joint):
        if isinstance(spec, (int, float)):
            return float(spec)
        return float(spec.get(joint, spec["default"]))

    included = [STANDARD.index(j) for j in settings["joints"]]
    return {
        "joints": included,
        "norm": settings.get("norm", "l2"),
        "velocity_terms": settings.get("velocity_terms", True),
        "heading_weight": float(settings.get("heading_weight", 0)),
        "continuity_weight": float(settings.get("continuity_weight", 0)),
        "lookahead_distance": None
        if settings.get("lookahead_distance") is None
        else float(settings["lookahead_distance"]),
        "graph_lookahead": bool(settings.get("graph_lookahead", False)),
        "graph_cost_to_go": bool(settings.get("graph_cost_to_go", True)),
        **{
            k: np.array([per_joint(settings[k], STANDARD[j]) for j in included])
            for k in (
                "position_threshold",
                "angle_threshold",
                "velocity_threshold",
                "angular_velocity_threshold",
            )
        },
    }


def _sum(x: np.ndarray) -> np.ndarray:
    """The sum over the last (short) axis, written out in numpy's order (its reduction over an axis
    of 3 or 4 is several times slower)."""
    total = x[..., 0]
    for k in range(1, x.shape[-1]):
        total = total + x[..., k]
    return total


def _length(x: np.ndarray, norm: str = "l2") -> np.ndarray:
    """np.linalg.norm over the last axis (or the L1 norm)."""
    return _sum(np.abs(x)) if norm == "l1" else np.sqrt(_sum(x * x))


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.abs(_sum(a * b)) / (_length(a) * _length(b))
    return 2 * np.arccos(np.clip(d, -1, 1))


def ratios(prev: dict, cand: dict, plan: dict) -> np.ndarray:
    """prev: arrays of one terminator; cand: arrays over candidates. Largest
    difference/threshold."""
    j = plan["joints"]
    dist = _length(cand["pos"][:, j] - prev["pos"][j], plan["norm"])
    terms = [
        dist / plan["position_threshold"],
        quat_angle(cand["rot"][:, j], prev["rot"][j]) / plan["angle_threshold"],
    ]
    if plan["velocity_terms"]:
        terms.append(_length(cand["vel"][:, j] - prev["vel"][j]) / plan["velocity_threshold"])
        terms.append(
            _length(cand["angvel"][:, j] - prev["angvel"][j]) / plan["angular_velocity_threshold"]
        )
    return np.max(np.concatenate(terms, axis=1), axis=1)


def target_cost(
    net: np.ndarray, turn: np.ndarray, target, heading_weight: float, lookahead: float | None = None
) -> np.ndarray:
    t = np.asarray(target, dtype=np.float64)
    ground = np.array([0, -1]) if len(t) == 2 else np.array([0, 2])
    reach = np.hypot(*t[ground])
    # score against the point that far toward the target
    if lookahead is not None and reach > lookahead:
        t[ground] *= lookahead / reach
    if len(t) == 3:
        d = np.linalg.norm(net - t, axis=1)
    else:
        d = np.hypot(net[:, 0] - t[0], net[:, 2] - t[1])
    direction = np.arctan2(t[0], t[-1])
    wrapped = np.angle(np.exp(1j * (turn - direction)))
    return d + heading_weight * np.abs(wrapped)


def level0_ratios(
    space: dict, members: np.ndarray, plan: dict, within: float = np.inf, block: int = 128
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each snippet index p of `members`: (indices of the members that may follow it, their
    ratios), before the ratio test: same poses and rate, no replay of p's frames (the seam aside).
    Only the pairs whose ratio is at most `within`: the terms of `ratios` one at a time (a kind of
    term at one joint), each over the pairs that the earlier ones kept within it, for `block`
    snippets p at a time."""
    members = np.asarray(members)
    j = plan["joints"]
    cand = {k: space[k][members][:, j] for k in ("pos", "rot", "vel", "angvel")}
    ends = {k: np.stack([space["end"][p][k] for p in members])[:, j] for k in cand}
    pose, fps = space["pose"][members], space["fps"][members]
    clip, version = space["clip"][members], space["version"][members]
    lo, hi = space["first"][members] + 1, space["first"][members] + space["n"][members] - 1

    def term(kind, k, a, b):
        """One kind of term at the k-th included joint, for the pairs (members[a], members[b])."""
        if kind == "pos":
            dist = _length(cand["pos"][b, k] - ends["pos"][a, k], plan["norm"])
            return dist / plan["position_threshold"][k]
        if kind == "rot":
            return quat_angle(cand["rot"][b, k], ends["rot"][a, k]) / plan["angle_threshold"][k]
        threshold = plan["velocity_threshold" if kind == "vel" else "angular_velocity_threshold"]
        return _length(cand[kind][b, k] - ends[kind][a, k]) / threshold[k]

    kinds = ["pos", "rot"] + (["vel", "angvel"] if plan["velocity_terms"] else [])
    out = {}
    for start in range(0, len(members), block):
        rows = np.arange(start, min(start + block, len(members)))
        ok = (pose == pose[rows, None]) & (fps == fps[rows, None])
        ok &= ~(
            (clip == clip[rows, None])
            & (version == version[rows, None])
            & (lo[rows, None] <= hi)
            & (lo <= hi[rows, None])
        )
        # every pair of the block at once while most are left, then only the pairs left
        ratio, left = np.zeros(ok.shape), ok
        a, b = rows[:, None], slice(None)
        for kind in kinds:
            for k in range(len(j)):
                ratio = np.maximum(ratio, term(kind, k, a, b))
                if left is not None:
                    left &= ratio <= within
                    if left.mean() < 0.2 or (kind == kinds[-1] and k == len(j) - 1):
                        a, b = np.nonzero(left)
                        ratio, left = ratio[a, b], None
                        a += start
                else:
                    keep = ratio <= within
                    a, b, ratio = a[keep], b[keep], ratio[keep]
        bounds = np.searchsorted(a, rows, side="left").tolist() + [len(a)]
        for k, row in enumerate(rows):
            out[int(members[row])] = (
                members[b[bounds[k] : bounds[k + 1]]],
                ratio[bounds[k] : bounds[k + 1]],
            )
    return out


def strong_components(nodes, successors: dict) -> list[set]:
    """The sets of nodes that all reach each other (scipy's strongly connected components of the
    graph of `successors`: node -> the nodes it links to)."""
    nodes = list(nodes)
    index = {n: k for k, n in enumerate(nodes)}
    links = [(index[n], index[m]) for n in nodes for m in successors[n]]
    a, b = np.array(links, dtype=np.int64).reshape(-1, 2).T
    graph = csr_matrix((np.ones(len(a)), (a, b)), shape=(len(nodes), len(nodes)))
    count, labels = connected_components(graph, directed=True, connection="strong")
    components: list[set] = [set() for _ in range(count)]
    for n, label in zip(nodes, labels.tolist()):
        components[label].add(n)
    return components


def levels(r: np.ndarray) -> np.ndarray:
    return np.select([r <= 1, r <= 2, r <= 4, r <= 8], [0, 1, 2, 3], 4)


def _pose(hierarchy: dict) -> str:
    """What two snippets must share to follow each other: the joints, their parents and channels,
    and the offsets of the joints without position channels."""
    return json.dumps(
        [
            (
                j["name"],
                j["parent"],
                j["channels"],
                None
                if {"Xposition", "Yposition", "Zposition"} <= set(j["channels"])
                or {"TX", "TY", "TZ"} <= set(j["channels"])
                else j["offset"],
            )
            for j in hierarchy["joints"]
        ]
    )


def load_snippet_space(conn) -> dict:
    """Every snippet's data as the oracle computes it, keyed by position in arrays ("pose": one
    number per distinct _pose, "end": one dict of terminator arrays per snippet)."""
    from modb.clips import read_motion  # reads frames only; terminators are recomputed here

    rows = conn.execute(
        "SELECT s.id, s.clip_id, s.version, s.first_frame, s.n_frames, s.collection_id, s.fps, "
        "       v.skeleton_id FROM modb.snippets s JOIN modb.clip_versions v USING (clip_id, "
        "version) "
        "WHERE NOT s.mirrored ORDER BY s.id"
    ).fetchall()
    skeletons = {
        sid: (h, m)
        for sid, h, m in conn.execute("SELECT id, hierarchy, joint_map FROM modb.skeletons")
    }
    poses: dict[str, int] = {}
    pose_of = {sid: poses.setdefault(_pose(h), len(poses)) for sid, (h, _) in skeletons.items()}
    n = len(rows)
    out = {
        "id": np.array([r[0] for r in rows]),
        "clip": np.array([r[1] for r in rows]),
        "version": np.array([r[2] for r in rows]),
        "first": np.array([r[3] for r in rows]),
        "n": np.array([r[4] for r in rows]),
        "collection": np.array([r[5] for r in rows]),
        "fps": np.array([r[6] for r in rows]),
        "pose": np.array([pose_of[r[7]] for r in rows]),
        "end": [None] * n,
    }
    for key, shape in (("pos", (19, 3)), ("rot", (19, 4)), ("vel", (19, 3)), ("angvel", (19, 3))):
        out[key] = np.zeros((n, *shape))
    for key, shape in (("feat", (49,)), ("net", (3,)), ("future", (3,))):
        out[key] = np.zeros((n, *shape))
    out["net_turn"], out["future_turn"] = np.zeros(n), np.zeros(n)
    starts = {(clip, version, first) for _, clip, version, first, *_ in rows}
    by_clip: dict = {}
    for k, (_, clip, version, *_rest) in enumerate(rows):
        by_clip.setdefault((clip, version), []).append(k)
    for (clip, version), at in by_clip.items():
        at = np.array(at)
        fps, skeleton = rows[at[0]][6], rows[at[0]][7]
        motion = read_motion(conn, clip, version)
        h, jm = skeletons[skeleton]
        t = clip_terms(
            h,
            jm,
            motion.rotations.astype(np.float32).astype(np.float64),
            motion.translations.astype(np.float32).astype(np.float64),
            fps,
        )
        first = out["first"][at]
        last = first + out["n"][at] - 1
        for key in ("pos", "rot", "vel", "angvel", "feat"):
            out[key][at] = getattr(t, key)[first]
        for k, f in zip(at.tolist(), last.tolist()):
            out["end"][k] = {
                key: getattr(t, key)[f] for key in ("pos", "rot", "vel", "angvel", "feat")
            }
        to_local = _yaw(t.heading[first]).inv()
        out["net"][at] = to_local.apply(t.pelvis[last] - t.pelvis[first])
        out["net_turn"][at] = np.angle(np.exp(1j * (t.heading[last] - t.heading[first])))
        # Where playing on leads: this window and up to two more, each starting on the last one's
        # end.
        end = last.copy()
        for k, n_frames in enumerate(out["n"][at].tolist()):
            for _ in range(2):
                if (clip, version, int(end[k])) not in starts:
                    break
                end[k] += n_frames - 1
        out["future"][at] = to_local.apply(t.pelvis[end] - t.pelvis[first])
        out["future_turn"][at] = np.angle(np.exp(1j * (t.heading[end] - t.heading[first])))
    return out


def two_step_cost(space: dict, i: int, nexts: np.ndarray, target, plan: dict) -> float:
    """The best objective among the snippets that may follow snippet i, each placed where i ends:
    the target seen from there (i's end point, turned by i's heading change)."""
    if not len(nexts):
        return np.inf
    t = np.asarray(target, dtype=np.float64)
    world = np.array([t[0], 0.0, t[-1]]) if len(t) == 2 else t.copy()
    seen = (
        _yaw([space["net_turn"][i]])
        .inv()
        .apply(world - space["net"][i] * [1, 0 if len(t) == 2 else 1, 1])[0]
    )
    local = [seen[0], seen[2]] if len(t) == 2 else list(seen)
    return float(
        min(
            np.minimum(
                *(
                    target_cost(
                        space[at][nexts],
                        space["future_turn"][nexts],
                        local,
                        plan["heading_weight"],
                        plan["lookahead_distance"],
                    )
                    for at in ("net", "future")
                )
            )
        )
    )


def duration_of(space: dict, i: int) -> float:
    return (space["n"][i] - 1) / space["fps"][i]


def _seen_from_end(space: dict, i: int, points) -> np.ndarray:
    """Points {x, z} or {x, y, z} of snippet i's start frame, as (x, z) seen from its end."""
    t = np.atleast_2d(np.asarray(points, dtype=np.float64))
    world = np.stack([t[:, 0], np.zeros(len(t)), t[:, -1]], axis=1)
    seen = _yaw([space["net_turn"][i]]).inv().apply(world - space["net"][i] * [1, 0, 1])
    return seen[:, [0, 2]]


def read_costs(tables: np.ndarray, grid: dict, xz: np.ndarray) -> np.ndarray:
    """Cost-to-go tables (n, angles, rings), each read at its own goals (x, z) xz (n, goals, 2):
    linear in (angle, log radius) by scipy, 0 within the inner radius, the outer ring plus the
    distance beyond it at the grid's speed. One scipy call: the table's index is one more grid axis,
    read at whole numbers only."""
    angles, rings, inner, outer = (
        grid["angles"],
        grid["rings"],
        grid["inner_radius"],
        grid["outer_radius"],
    )
    r = np.hypot(xz[..., 0], xz[..., 1])
    u = np.clip(
        np.log(np.maximum(r, 1e-12) / inner) / np.log(outer / inner) * (rings - 1), 0, rings - 1
    )
    a = np.mod(np.arctan2(xz[..., 0], xz[..., 1]), 2 * np.pi) / (2 * np.pi / angles)
    wrapped = np.concatenate([tables, tables[:, :1]], axis=1)  # angle A is angle 0 again
    wrapped = np.concatenate([wrapped, wrapped[-1:]])  # (scipy's linear needs two on every axis)
    which = np.broadcast_to(np.arange(len(tables))[:, None], r.shape)
    value = RegularGridInterpolator(
        (np.arange(len(tables) + 1), np.arange(angles + 1), np.arange(rings)), wrapped
    )(np.stack([which, a, u], axis=-1))
    return np.where(r <= inner, 0.0, value + np.maximum(r - outer, 0) / grid["speed"])


def interpolation(grid: dict, xz: np.ndarray) -> tuple[csr_matrix, np.ndarray]:
    """read_costs at fixed goals as a linear map: (W, beyond) such that read_costs(tables, grid, xz)
    is (W @ tables.ravel() + beyond) for any tables (n, angles, rings), xz (n, goals, 2) flattened
    to (n x goals): linear in (angle, log radius), with scipy's cells and weights, checked against
    read_costs on random tables."""
    angles, rings, inner, outer = (
        grid["angles"],
        grid["rings"],
        grid["inner_radius"],
        grid["outer_radius"],
    )
    n, goals = xz.shape[:2]
    r = np.hypot(xz[..., 0], xz[..., 1]).ravel()
    u = np.clip(
        np.log(np.maximum(r, 1e-12) / inner) / np.log(outer / inner) * (rings - 1), 0, rings - 1
    )
    a = np.mod(np.arctan2(xz[..., 0], xz[..., 1]), 2 * np.pi).ravel() / (2 * np.pi / angles)
    ia = np.minimum(np.floor(a), angles - 1).astype(np.int64)
    iu = np.minimum(np.floor(u), rings - 2).astype(np.int64)
    fa, fu = a - ia, u - iu
    table = np.repeat(np.arange(n), goals) * angles * rings
    outside = r > inner
    rows, cols, weights = [], [], []
    for da, wa in ((0, 1 - fa), (1, fa)):
        for du, wu in ((0, 1 - fu), (1, fu)):
            rows.append(np.flatnonzero(outside))
            cols.append((table + (ia + da) % angles * rings + iu + du)[outside])
            weights.append((wa * wu)[outside])
    w = csr_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n * goals, n * angles * rings),
    )
    beyond = np.where(outside, np.maximum(r - outer, 0) / grid["speed"], 0.0)
    tables = np.random.default_rng(0).uniform(0, 60, size=(n, angles, rings))
    scipy_read = read_costs(tables, grid, xz).ravel()
    assert np.allclose(w @ tables.ravel() + beyond, scipy_read, rtol=1e-12, atol=1e-9)
    return w, beyond


def cost_to_go(
    space: dict, successors: dict, seam: dict, grid: dict, tolerance: float = 1e-6
) -> dict:
    """Value iteration from zero: snippet index -> (angles x rings) least seconds (snippet
    durations, plus seam[(from, to)] per transition) until a chain through the graph (successors:
    index -> indices) ends within the inner radius of a goal at each grid point. Each iteration
    reads every table where each successor ends (read_costs, as a fixed linear map) and takes the
    least over each snippet's transitions."""
    angles, rings = grid["angles"], grid["rings"]
    theta = np.arange(angles) * 2 * np.pi / angles
    radii = np.geomspace(grid["inner_radius"], grid["outer_radius"], rings)
    points = np.stack(
        [np.outer(np.sin(theta), radii).ravel(), np.outer(np.cos(theta), radii).ravel()], axis=1
    )
    # the snippets by their number of transitions, most first
    order = sorted(successors, key=lambda i: -len(successors[i]))
    row = {i: k for k, i in enumerate(order)}
    seen = np.stack([_seen_from_end(space, i, points) for i in order])
    duration = np.array([duration_of(space, i) for i in order])[:, None]
    read, beyond = interpolation(grid, seen)
    beyond = beyond.reshape(len(order), len(points)) + duration
    # Slot k: the k-th transition of every snippet that has more than k (the first rows).
    degree = np.array([len(successors[i]) for i in order])
    assert degree.min() > 0, "a snippet without transitions"
    slots = [
        (
            np.array([row[int(successors[i][k])] for i in order[: (degree > k).sum()]]),
            np.array([seam[i, int(successors[i][k])] for i in order[: (degree > k).sum()]]),
        )
        for k in range(degree.max())
    ]
    values = np.zeros((len(order), angles * rings))
    new, part = np.empty_like(values), np.empty_like(values)
    while True:
        through = (read @ values.ravel()).reshape(values.shape) + beyond
        for k, (to, cost) in enumerate(slots):
            rows = len(to)
            np.take(through, to, axis=0, out=part[:rows] if k else new)
            if k:
                np.add(part[:rows], cost[:, None], out=part[:rows])
                np.minimum(new[:rows], part[:rows], out=new[:rows])
            else:
                new += cost[:, None]
        new.reshape(-1, angles, rings)[:, :, 0] = 0.0
        change = np.abs(new - values).max()
        values, new = new, values
        if change < tolerance:
            return {i: values[row[i]].reshape(angles, rings) for i in order}


def select(
    space: dict,
    prev_id,
    target,
    plan: dict,
    collections=None,
    exclude=(),
    graph=None,
    successors=None,
    costs=None,
    grid=None,
) -> list[tuple[int, float, int, float]]:
    """Every eligible snippet as (level, order key, id, continuity ratio), best first. graph: the
    snippet ids of a transition graph, the only ones eligible; successors: its level-0 transitions
    (snippet index -> indices of those that may follow it), for graph_lookahead when prev lies in
    it; costs and grid: its cost-to-go tables (snippet index -> angles x rings) and their grid,
    which rank level 0 when prev lies in it."""
    ids = space["id"]
    ok = np.ones(len(ids), dtype=bool)
    if graph is not None:
        ok &= np.isin(ids, list(graph))
    if collections is not None:
        ok &= np.isin(space["collection"], list(collections))
    # prev's own frames: no replay
    for x in set(exclude) | ({prev_id} if prev_id is not None else set()):
        k = int(np.flatnonzero(ids == x)[0])
        same = (space["clip"] == space["clip"][k]) & (space["version"] == space["version"][k])
        cand_lo, cand_hi = space["first"] + 1, space["first"] + space["n"] - 1
        ex_lo, ex_hi = space["first"][k] + 1, space["first"][k] + space["n"][k] - 1
        ok &= ~(same & (ex_lo <= cand_hi) & (cand_lo <= ex_hi))
    # The nearer of the snippet's end and where playing on leads (the heading term is the same for
    # both).
    cost = np.minimum(
        *(
            target_cost(
                space[at],
                space["future_turn"],
                target,
                plan["heading_weight"],
                plan["lookahead_distance"],
            )
            for at in ("net", "future")
        )
    )
    if prev_id is None:
        level = np.zeros(len(ids), dtype=int)
        order_key = cost
        ratio = np.zeros(len(ids))
    else:
        p = int(np.flatnonzero(ids == prev_id)[0])
        ok &= (space["pose"] == space["pose"][p]) & (space["fps"] == space["fps"][p])
        prev = space["end"][p]
        # (the ratios of the eligible snippets: the others' are never read)
        ratio = np.zeros(len(ids))
        ratio[ok] = ratios(prev, {k: space[k][ok] for k in ("pos", "rot", "vel", "angvel")}, plan)
        level = levels(ratio)
        if plan["graph_cost_to_go"] and costs is not None and p in successors:
            at = np.flatnonzero(ok & (level == 0))
            if len(at):  # each one's table, read where the target lies seen from its end
                seen = np.stack([_seen_from_end(space, i, target) for i in at])
                tables = np.stack([costs[i] for i in at])
                seconds = np.array([duration_of(space, i) for i in at])
                cost[at] = grid["speed"] * (seconds + read_costs(tables, grid, seen)[:, 0])
        elif plan["graph_lookahead"] and successors is not None and p in successors:
            for i in np.flatnonzero(ok & (level == 0)):
                cost[i] = min(cost[i], two_step_cost(space, i, successors[i], target, plan))
        order_key = np.where(
            level == 4,
            np.linalg.norm(space["feat"] - prev["feat"], axis=1),
            cost + plan["continuity_weight"] * ratio,
        )
    at = np.flatnonzero(ok)
    # sorted as the tuples (level, order key, id, ratio) sort
    at = at[np.lexsort((ratio[at], ids[at], order_key[at], level[at]))]
    return list(
        zip(
            level[at].tolist(),
            order_key[at].tolist(),
            ids[at].tolist(),
            ratio[at].tolist(),
        )
    )
