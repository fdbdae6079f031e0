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


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.abs(np.sum(a * b, axis=-1)) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return 2 * np.arccos(np.clip(d, -1, 1))


def ratios(prev: dict, cand: dict, plan: dict) -> np.ndarray:
    """prev: arrays of one terminator; cand: arrays over candidates. Largest
    difference/threshold."""
    j = plan["joints"]
    dp = cand["pos"][:, j] - prev["pos"][j]
    dist = np.abs(dp).sum(axis=-1) if plan["norm"] == "l1" else np.linalg.norm(dp, axis=-1)
    terms = [
        dist / plan["position_threshold"],
        quat_angle(cand["rot"][:, j], prev["rot"][j]) / plan["angle_threshold"],
    ]
    if plan["velocity_terms"]:
        terms.append(
            np.linalg.norm(cand["vel"][:, j] - prev["vel"][j], axis=-1) / plan["velocity_threshold"]
        )
        terms.append(
            np.linalg.norm(cand["angvel"][:, j] - prev["angvel"][j], axis=-1)
            / plan["angular_velocity_threshold"]
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
    space: dict, members: np.ndarray, plan: dict
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each snippet index p of `members`: (indices of the members that may follow it, their
    ratios), before the ratio test: same poses and rate, no replay of p's frames (the seam aside).
    """
    out = {}
    cand = {k: space[k][members] for k in ("pos", "rot", "vel", "angvel")}
    pose = np.array(space["pose"])[members]
    for p in members:
        ok = (pose == space["pose"][p]) & (space["fps"][members] == space["fps"][p])
        same = (space["clip"][members] == space["clip"][p]) & (
            space["version"][members] == space["version"][p]
        )
        lo, hi = space["first"][members] + 1, space["first"][members] + space["n"][members] - 1
        ok &= ~(
            same & (space["first"][p] + 1 <= hi) & (lo <= space["first"][p] + space["n"][p] - 1)
        )
        out[int(p)] = (
            members[ok],
            ratios(space["end"][p], {k: v[ok] for k, v in cand.items()}, plan),
        )
    return out


def strong_components(nodes, successors: dict) -> list[set]:
    """The sets of nodes that all reach each other: for each node not yet placed, the nodes it
    reaches that also reach it (two breadth-first searches)."""
    predecessors: dict = {n: [] for n in nodes}
    for n in nodes:
        for m in successors[n]:
            predecessors[m].append(n)

    def reach(start, links):
        seen, todo = {start}, [start]
        while todo:
            for m in links[todo.pop()]:
                if m not in seen:
                    seen.add(m)
                    todo.append(m)
        return seen

    placed: set = set()
    components = []
    for n in nodes:
        if n not in placed:
            component = reach(n, successors) & reach(n, predecessors)
            placed |= component
            components.append(component)
    return components


def levels(r: np.ndarray) -> np.ndarray:
    return np.select([r <= 1, r <= 2, r <= 4, r <= 8], [0, 1, 2, 3], 4)


def load_snippet_space(conn) -> dict:
    """Every snippet's data as the oracle computes it, keyed by position in arrays."""
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
    cache: dict = {}
    out = {
        k: []
        for k in (
            "id",
            "clip",
            "version",
            "first",
            "n",
            "collection",
            "fps",
            "pose",
            "pos",
            "rot",
            "vel",
            "angvel",
            "feat",
            "net",
            "net_turn",
            "future",
            "future_turn",
            "end",
        )
    }
    starts = {(clip, version, first) for _, clip, version, first, *_ in rows}
    for sid, clip, version, first, n_frames, collection, fps, skeleton in rows:
        if (clip, version) not in cache:
            motion = read_motion(conn, clip, version)
            h, jm = skeletons[skeleton]
            cache[(clip, version)] = clip_terms(
                h,
                jm,
                motion.rotations.astype(np.float32).astype(np.float64),
                motion.translations.astype(np.float32).astype(np.float64),
                fps,
            )
        t = cache[(clip, version)]
        h = skeletons[skeleton][0]
        pose = json.dumps(
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
                for j in h["joints"]
            ]
        )
        last = first + n_frames - 1
        for key, value in (
            ("id", sid),
            ("clip", clip),
            ("version", version),
            ("first", first),
            ("n", n_frames),
            ("collection", collection),
            ("fps", fps),
            ("pose", pose),
        ):
            out[key].append(value)
        for key, arr in (
            ("pos", t.pos),
            ("rot", t.rot),
            ("vel", t.vel),
            ("angvel", t.angvel),
            ("feat", t.feat),
        ):
            out[key].append(arr[first])
        out["end"].append(
            {
                "pos": t.pos[last],
                "rot": t.rot[last],
                "vel": t.vel[last],
                "angvel": t.angvel[last],
                "feat": t.feat[last],
            }
        )
        to_local = _yaw([t.heading[first]]).inv()
        out["net"].append(to_local.apply(t.pelvis[last] - t.pelvis[first])[0])
        out["net_turn"].append(np.angle(np.exp(1j * (t.heading[last] - t.heading[first]))))
        # Where playing on leads: this window and up to two more, each starting on the last one's
        # end.
        end = last
        for _ in range(2):
            if (clip, version, end) not in starts:
                break
            end += n_frames - 1
        out["future"].append(to_local.apply(t.pelvis[end] - t.pelvis[first])[0])
        out["future_turn"].append(np.angle(np.exp(1j * (t.heading[end] - t.heading[first]))))
    return {k: (np.array(v) if k not in ("end", "pose") else v) for k, v in out.items()}


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


def read_cost(table: np.ndarray, grid: dict, xz: np.ndarray) -> np.ndarray:
    """A cost-to-go table (angles x rings) read at goals (x, z): linear in (angle, log radius) by
    scipy, 0 within the inner radius, the outer ring plus the distance beyond it at the grid's
    speed."""
    return read_costs(table[None], grid, xz[None])[0]


def read_costs(tables: np.ndarray, grid: dict, xz: np.ndarray) -> np.ndarray:
    """read_cost of many tables (n, angles, rings), each at its own goals xz (n, goals, 2), in one
    scipy call: the table's index is one more grid axis, read at whole numbers only."""
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


def cost_to_go(
    space: dict, successors: dict, seam: dict, grid: dict, tolerance: float = 1e-6
) -> dict:
    """Value iteration from zero: snippet index -> (angles x rings) least seconds (snippet
    durations, plus seam[(from, to)] per transition) until a chain through the graph (successors:
    index -> indices) ends within the inner radius of a goal at each grid point."""
    angles, rings = grid["angles"], grid["rings"]
    theta = np.arange(angles) * 2 * np.pi / angles
    radii = np.geomspace(grid["inner_radius"], grid["outer_radius"], rings)
    points = np.stack(
        [np.outer(np.sin(theta), radii).ravel(), np.outer(np.cos(theta), radii).ravel()], axis=1
    )
    order = list(successors)
    row = {i: k for k, i in enumerate(order)}
    seen = np.stack([_seen_from_end(space, i, points) for i in order])
    duration = np.array([duration_of(space, i) for i in order])[:, None]
    nexts = [np.array([row[int(t)] for t in successors[i]]) for i in order]
    seams = [np.array([seam[i, int(t)] for t in successors[i]])[:, None] for i in order]
    values = np.zeros((len(order), angles, rings))
    while True:
        through = duration + read_costs(values, grid, seen)
        new = np.stack([(through[n] + c).min(axis=0) for n, c in zip(nexts, seams)])
        new = new.reshape(values.shape)
        new[:, :, 0] = 0.0
        change = np.abs(new - values).max()
        values = new
        if change < tolerance:
            return {i: values[row[i]] for i in order}


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
        ok &= (np.array(space["pose"]) == space["pose"][p]) & (space["fps"] == space["fps"][p])
        prev = space["end"][p]
        cand = {k: space[k] for k in ("pos", "rot", "vel", "angvel")}
        ratio = ratios(prev, cand, plan)
        level = levels(ratio)
        if plan["graph_cost_to_go"] and costs is not None and p in successors:
            for i in np.flatnonzero(ok & (level == 0)):
                seconds = (
                    duration_of(space, i)
                    + read_cost(costs[i], grid, _seen_from_end(space, i, target))[0]
                )
                cost[i] = grid["speed"] * seconds
        elif plan["graph_lookahead"] and successors is not None and p in successors:
            for i in np.flatnonzero(ok & (level == 0)):
                cost[i] = min(cost[i], two_step_cost(space, i, successors[i], target, plan))
        order_key = np.where(
            level == 4,
            np.linalg.norm(space["feat"] - prev["feat"], axis=1),
            cost + plan["continuity_weight"] * ratio,
        )
    rows = [
        (int(level[i]), float(order_key[i]), int(ids[i]), float(ratio[i]))
        for i in np.flatnonzero(ok)
    ]
    return sorted(rows)
