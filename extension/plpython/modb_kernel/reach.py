"""A hand meeting a target at an action's keyframe, the pose kept natural (issue 63, item 4).

    result = reach.reach(parents, offsets, translated, names, joint_map, rotations, translations,
                         keyframe, {"right": (x, y, z)}, limits=model["limits"])
    result.rotations          # (frames, joints, 4), w first: the motion with the arm(s) moved
    result.after["right"]     # metres from the wrist to its target at the keyframe (and .before)
    result.reachable          # every target met within REACHED_M
    result.nearest["right"]   # None where met; else the point the wrist reaches nearest the target
    result.report()           # the same as plain JSON values

Arguments: the skeleton as kinematics.world_transforms takes it (parents, offsets, translated) with
its joint names and joint map (DESIGN.md "Joint map"); the motion's rotations (frames, joints, 4,
w first, relative to the parent) and translations (frames, len(translated), 3), which never change
(bone lengths are kept); the keyframe (a frame index); the targets, a mapping of side ("left",
"right", or both) to the world position the wrist (`left_wrist` / `right_wrist`: Bandai's
`Hand_L` / `Hand_R`) should have at the keyframe. Optional: limits, the examples' joint limits as a
motion model stores them (motion_model.joint_limits: {"mean": (joints, 4), "degrees": (joints,)});
slack_degrees, how far past them a moved joint may turn (the issue's 10 degrees); before / after,
how many frames before and after the keyframe the change reaches (default: to the motion's first
and last frame, which, like every frame outside the range, stay exactly as they were); spine,
whether the spine may help (default True).

How: the pose at the keyframe is solved by the kernel's chain solver (ik.solve: least squares of
the wrists to their targets over a few joints' turns, joint limits as its penalties), then carried
over the frames around it by the DFKI motion editor's cubic B-spline falloff (ik.falloff,
ik.spread_from), and each moved joint is kept within its allowance on every frame. The joints
and why:
- shoulder (upper arm): three degrees of freedom; elbow: one, a hinge about the axis the motion
  itself bends it about (its bend plane in the upper arm's frame, averaged over the motion,
  weighted by how bent the arm is), its bend kept on the motion's side (never straight-through
  or reversed: no hyperextension). Shoulder and elbow meet any target within the arm's length.
- the clavicle (the shoulder's parent, when it is not the chest) and the spine joints from the
  joint map's `spine` up to the clavicle's parent: the arm of a raised hand is nearly straight at
  its peak (Bandai's raises: 13-24 degrees of elbow bend, the wrist 0.46 of 0.466 m from the
  shoulder), so a target above or beyond the peak is out of the arm's length; the clavicle lifts
  the shoulder a few cm and the spine leans the chest toward the target, as people do. They cost
  more than the arm's joints (REGULARIZE), so a target the arm reaches moves them little.
- the wrist joint's own local rotation is kept (the hand turns with the forearm, as in the
  examples); legs, pelvis, neck and head are not turned (the head rides on the chest).
Joint limits are the solver's penalties, not a clamp afterwards (which would break the reach found
and say nothing of what remains): besides the wrists' offsets from their targets, each joint's turn
past its examples' range (a light weight: used when reaching needs it) and past the allowance (a
heavy one), the elbow's bend past straight, and the turns' pull toward the motion's own pose.
Where no pose within the allowance meets a target, the solver ends at the pose whose wrist is
nearest to it: that point and its distance are reported, the pose stays natural.
"""

from dataclasses import dataclass

import numpy as np

from . import ik, kinematics, quaternion

REACHED_M = 1e-3  # a target counts as met within this distance
SLACK_DEGREES = 10.0  # how far past the examples' range a moved joint may turn (issue 63)
SOLVE_INSIDE_DEGREES = 1.0  # the keyframe's pose is solved this far inside the allowance
LEAST_BEND_DEGREES = 1.0  # the elbow's least bend, on the motion's side
PAST_RANGE_WEIGHT = 0.02  # metres per radian: a turn past the examples' range (used when needed)
PAST_ALLOWANCE_WEIGHT = 30.0  # metres per radian: a turn past the allowance (not used)
# metres per radian: the pull of each kind of joint toward the motion's own pose
REGULARIZE = {"arm": 1e-3, "clavicle": 3e-3, "spine": 1e-2}
SIDES = ("left", "right")


@dataclass
class Reached:
    """What reach() did: the new rotations; per side the wrist's distance from its target at the
    keyframe before and after (metres), whether it met it (within REACHED_M), and where it did not
    the nearest point it reaches; the frames changed (first, last) and the joints moved."""

    rotations: np.ndarray
    before: dict
    after: dict
    met: dict
    nearest: dict
    frames: tuple
    joints: list

    @property
    def reachable(self):
        return all(self.met.values())

    def report(self):
        """Plain JSON values (the synthesis's report)."""
        return {
            "reachable": self.reachable,
            "before_m": {s: float(v) for s, v in self.before.items()},
            "after_m": {s: float(v) for s, v in self.after.items()},
            "met": dict(self.met),
            "nearest": {
                s: None if v is None else [float(x) for x in v] for s, v in self.nearest.items()
            },
            "frames": [int(f) for f in self.frames],
            "joints": list(self.joints),
        }


def arm_joints(parents, names, joint_map, side, spine=True):
    """{"spine": [...], "clavicle": [...], "shoulder", "elbow", "wrist"}: joint indices of one
    side's chain (the spine's list empty when it may not help, the clavicle's when the shoulder
    hangs on the chest itself)."""
    index = {n: i for i, n in enumerate(names)}
    try:
        shoulder, elbow, wrist = (index[joint_map[f"{side}_{p}"]]
                                  for p in ("shoulder", "elbow", "wrist"))  # fmt: skip
    except KeyError as e:
        raise ik.IKError(f"the joint map names no {side} arm joint {e}") from None
    if ik.path(parents, shoulder, wrist) != [shoulder, elbow, wrist]:
        raise ik.IKError(f"the {side} elbow is not between the shoulder and the wrist")
    clavicle = parents[shoulder]
    chest = index.get(joint_map.get("chest"), -1)
    clavicles = [] if clavicle < 0 or clavicle == chest else [clavicle]
    top = parents[clavicles[0]] if clavicles else clavicle
    spines = []
    if spine and top >= 0 and joint_map.get("spine") in index:
        try:
            spines = ik.path(parents, index[joint_map["spine"]], top)
        except ik.IKError:
            spines = []
    return {"spine": spines, "clavicle": clavicles, "shoulder": shoulder, "elbow": elbow,
            "wrist": wrist}  # fmt: skip


class _Limits:
    """The penalties ik.solve adds for the arms: each moved joint's turn past its examples' range
    and past the allowance, each elbow's bend short of LEAST_BEND_DEGREES on the motion's side."""

    def __init__(self, moved, limits, allowance, elbows, hinges, bends):
        self.moved, self.limits, self.allowance = moved, limits, allowance
        self.elbows, self.hinges, self.bends = elbows, hinges, bends

    def __call__(self, rotations, x):
        parts = []
        if self.limits is not None:
            mean, degrees = self.limits
            angle = quaternion.angle_between(rotations[:, self.moved], mean[None, self.moved])
            past = angle - np.radians(degrees[self.moved])[None]
            parts.append(PAST_RANGE_WEIGHT * np.maximum(past, 0.0))
            over = angle - self.allowance[None, self.moved]
            parts.append(PAST_ALLOWANCE_WEIGHT * np.maximum(over, 0.0))
        for k, j in enumerate(self.elbows):
            bend = _signed_bend(rotations[:, j], *self.bends[k], self.hinges[k])
            short = np.radians(LEAST_BEND_DEGREES) - bend
            parts.append(PAST_ALLOWANCE_WEIGHT * np.maximum(short, 0.0)[:, None])
        return parts


def _elbow_axis(rotations, local, elbow, wrist):
    """ik.hinge_axis, or for an arm straight throughout any normal to the upper arm."""
    axis = ik.hinge_axis(rotations, local, elbow, wrist)
    if axis is None:
        upper = ik.unit(local[0, elbow])
        axis = ik.unit(np.cross(upper, [0.0, 0.0, 1.0] if abs(upper[2]) < 0.9 else [1.0, 0, 0]))
    return axis


def _signed_bend(elbow_rotation, upper, fore, axis):
    """The elbow's bend (radians), positive on the motion's side: the angle from the upper arm's
    direction to the forearm's about the hinge axis, in the upper arm's frame."""
    f = quaternion.rotate(elbow_rotation, fore)
    return np.arctan2(np.cross(upper, f) @ axis, f @ upper)


def _signed_bend_frames(elbow_rotations, upper, fore, axis):
    """_signed_bend frame by frame (upper, fore: (frames, 3))."""
    f = quaternion.rotate(elbow_rotations, fore)
    return np.arctan2(np.sum(np.cross(upper, f) * axis, -1), np.sum(f * upper, -1))


def _clamped(rotations, mean, most):
    """Rotations (frames, 4) turned back toward mean where farther from it than most (radians,
    per frame): the same axis, the allowed angle (motion_model.within_limits, per frame)."""
    angle = quaternion.angle_between(rotations, mean[None])
    share = np.minimum(1.0, most / np.maximum(angle, 1e-12))[:, None]
    relative = quaternion.multiply(quaternion.conjugate(mean)[None], rotations)
    return quaternion.canonical(quaternion.multiply(mean[None], quaternion.power(relative, share)))


def reach(parents, offsets, translated, names, joint_map, rotations, translations, keyframe,
          targets, limits=None, slack_degrees=SLACK_DEGREES, before=None, after=None,
          spine=True):  # fmt: skip
    """Reached: the motion's arm(s) moved so that each side's wrist meets its target at the
    keyframe (see the module's docstring)."""
    parents = list(parents)
    rotations = np.asarray(rotations, dtype=np.float64)
    n_frames, n_joints = rotations.shape[:2]
    if not 0 <= keyframe < n_frames:
        raise ik.IKError(f"keyframe {keyframe} is outside the motion's {n_frames} frames")
    targets = {s: np.asarray(t, dtype=np.float64).reshape(3) for s, t in targets.items()}
    if not targets or set(targets) - set(SIDES):
        raise ik.IKError(f"targets are per side, 'left' and/or 'right': got {sorted(targets)}")
    before = keyframe if before is None else int(min(max(before, 0), keyframe))
    after = (
        n_frames - 1 - keyframe
        if after is None
        else int(min(max(after, 0), n_frames - 1 - keyframe))
    )
    chains = {s: arm_joints(parents, names, joint_map, s, spine) for s in SIDES if s in targets}
    local = ik.local_offsets(offsets, translated, translations)
    hinges, bends = [], []
    for c in chains.values():
        e, w = c["elbow"], c["wrist"]
        hinges.append(_elbow_axis(rotations, local, e, w))
        bends.append((ik.unit(local[keyframe, e]), ik.unit(local[keyframe, w])))
    pose = rotations[keyframe]
    lim = allowance = None
    if limits is not None:
        mean = quaternion.canonical(np.asarray(limits["mean"], dtype=np.float64))
        degrees = np.asarray(limits["degrees"], dtype=np.float64)
        if mean.shape != (n_joints, 4) or degrees.shape != (n_joints,):
            raise ik.IKError(f"limits are for {len(degrees)} joints, the motion has {n_joints}")
        lim = (mean, degrees)
        # a joint the motion itself turns past the allowance may stay where it is
        own = quaternion.angle_between(pose, mean)
        allowance = np.maximum(np.radians(degrees + slack_degrees - SOLVE_INSIDE_DEGREES), own)
    moved, cost = [], {}
    for c in chains.values():
        for kind, joints in (("spine", c["spine"]), ("clavicle", c["clavicle"]),
                             ("arm", [c["shoulder"]])):  # fmt: skip
            moved += [j for j in joints if j not in moved]
            cost.update({j: REGULARIZE[kind] for j in joints})
    elbows = [c["elbow"] for c in chains.values()]
    cost.update({e: REGULARIZE["arm"] for e in elbows})
    moved += elbows
    wrists = [c["wrist"] for c in chains.values()]
    turns = ik.Turns(parents, local[keyframe], pose, moved, wrists, dict(zip(elbows, hinges)), cost)
    wanted = np.stack([targets[s] for s in chains])
    start = dict(zip(chains, np.linalg.norm(turns.ends_at(pose[None])[0] - wanted, axis=-1)))
    penalties = _Limits(moved, lim, allowance, elbows, hinges, bends)
    changed, _ = ik.solve(turns, wanted, penalties)
    weights = ik.falloff(n_frames, keyframe, before, after)
    out = ik.spread_from(rotations, keyframe, changed, moved, weights)
    if lim is not None:  # every frame's moved joints within the allowance (or their own turn)
        mean, degrees = lim
        for j in moved:
            own = quaternion.angle_between(rotations[:, j], mean[j][None])
            most = np.maximum(np.radians(degrees[j] + slack_degrees - 0.5), own)
            out[:, j] = _clamped(out[:, j], mean[j], most)
    # the keyframe's change carried to a frame less bent than it may straighten that frame's
    # elbow past straight: each frame's bend kept at LEAST_BEND_DEGREES (or the motion's own)
    for k, c in enumerate(chains.values()):
        e, w = c["elbow"], c["wrist"]
        upper, fore = ik.unit(local[:, e]), ik.unit(local[:, w])
        bend = _signed_bend_frames(out[:, e], upper, fore, hinges[k])
        own = _signed_bend_frames(rotations[:, e], upper, fore, hinges[k])
        short = np.minimum(np.radians(LEAST_BEND_DEGREES), own) - bend
        short[short < 0.0] = 0.0
        turn = quaternion.from_rotation_vector(short[:, None] * hinges[k][None])
        out[:, e] = quaternion.canonical(quaternion.multiply(turn, out[:, e]))
    untouched = weights <= 0.0
    out[untouched] = rotations[untouched]  # byte for byte
    ends = kinematics.world_positions(parents, offsets, out[keyframe:keyframe + 1],
                                      np.asarray(translations)[keyframe:keyframe + 1],
                                      translated)[0]  # fmt: skip
    after_m, met, nearest = {}, {}, {}
    for s, c in chains.items():
        wrist = ends[c["wrist"]]
        after_m[s] = float(np.linalg.norm(wrist - targets[s]))
        met[s] = after_m[s] <= REACHED_M
        nearest[s] = None if met[s] else wrist
    changed_frames = np.flatnonzero(~untouched)
    frames = (int(changed_frames[0]), int(changed_frames[-1])) if len(changed_frames) else ()
    return Reached(out, start, after_m, met, nearest, frames, [names[j] for j in moved])
