"""Inverse kinematics: one solver for the feet, actions and the motion editor.

- two_bone: a limb of two bones (hip-knee-ankle, shoulder-elbow-wrist) reaches a target
  analytically. The limb bends in the plane of its pole: by default the direction the middle
  joint points to in the motion itself (the knee's or the elbow's way kept), or a given world
  direction. The end joint keeps its world orientation (the foot stays as it was turned) unless
  one is given. A target out of reach is met as nearly as the limb can: the end joint on the line
  from the limb's root toward the target, at the limb's full (or least) length.
- solve (with Turns): the chain solver the actions' arm (reach.py) and the edit scripts' `ik`
  (pose_edits.py) share: one frame's pose, some joints turned (ball joints freely, an elbow or a
  knee as a hinge about the axis the motion bends it about, hinge_axis) so that one or more end
  joints meet their targets, by least squares with each turn's cost (the pull toward the motion's
  own pose) and any penalties the caller adds (reach: joint limits, the elbow's side). two_bone
  is its closed form for a limb without limits, fast over every frame at once: the feet's.
- spread: a change made at one frame carried over the frames around it, each joint's change
  weighted by a cubic B-spline bump (1 at the frame, falling smoothly to 0 at the range's ends).

Poses are the kernel's: per frame, a unit quaternion per joint relative to its parent, and local
translations of the joints with position channels (kinematics.world_transforms). two_bone and
spread work on many frames at once, solve on one; each returns new rotations; translations never
change, so bone lengths are kept. A chain is given by joint indices, from its root to its end;
joints between them in the hierarchy are carried along.
"""

import numpy as np
from scipy.interpolate import BSpline

from . import kinematics, quaternion

FINITE_STEP = 1e-7  # radians: the solver's Jacobian by forward differences
EVALUATIONS = 200  # the solver's most evaluations
STRAIGHT = 1e-3  # of a bone's length: a middle joint nearer the limb's line has no bend of its own
_BUMP = BSpline.basis_element(np.array([-2.0, -1.0, 0.0, 1.0, 2.0]), extrapolate=False)


class IKError(ValueError):
    pass


def path(parents, root, end):
    """Joint indices from root down to end (both included) along the hierarchy."""
    out = [end]
    while out[-1] != root:
        parent = parents[out[-1]]
        if parent < 0:
            raise IKError(f"joint {end} does not descend from joint {root}")
        out.append(parent)
    return out[::-1]


def unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300)


def arc(u, v):
    """The shortest rotation taking directions u to v (..., 3); opposite directions turn about an
    axis normal to u."""
    u, v = unit(u), unit(v)
    cross = np.cross(u, v)
    dot = np.sum(u * v, axis=-1, keepdims=True)
    q = np.concatenate([1.0 + dot, cross], axis=-1)
    opposite = (1.0 + dot[..., 0]) < 1e-9
    if np.any(opposite):
        other = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        axis = unit(np.cross(u, other))
        q[opposite] = np.concatenate([np.zeros_like(dot), axis], axis=-1)[opposite]
    return quaternion.canonical(q)


def _local(world, parent_world):
    return quaternion.canonical(quaternion.multiply(quaternion.conjugate(parent_world), world))


def _parent_orientation(parents, orientations, joint):
    parent = parents[joint]
    if parent < 0:
        return np.broadcast_to([1.0, 0.0, 0.0, 0.0], orientations[:, joint].shape)
    return orientations[:, parent]


def two_bone(parents, offsets, rotations, translations, translated, chain, targets,
             poles=None, end_orientations=None):  # fmt: skip
    """(rotations, reached, miss): the limb chain = (root, middle, end) turned so that the end
    joint reaches targets (frames, 3); reached is where it ends up and miss its distance from the
    target (0 where reachable). poles: world directions (frames, 3) the middle joint bends toward,
    else the motion's own (_motion_poles); end_orientations: world quaternions (frames, 4) for the
    end joint, else its own."""
    root, middle, end = chain
    rotations = np.array(rotations, dtype=np.float64)
    positions, orientations = kinematics.world_transforms(parents, offsets, rotations,
                                                          translations, translated)  # fmt: skip
    a, b, c = positions[:, root], positions[:, middle], positions[:, end]
    targets = np.broadcast_to(np.asarray(targets, dtype=np.float64), a.shape)
    upper = np.linalg.norm(b - a, axis=-1)
    lower = np.linalg.norm(c - b, axis=-1)
    # The bend's side: the middle joint's offset from the limb's line (or the pole given).
    line = unit(c - a)
    bend = (b - a) - np.sum((b - a) * line, -1, keepdims=True) * line
    if poles is None:
        poles = _motion_poles(bend, orientations[:, middle])
    to_target = targets - a
    wanted = np.linalg.norm(to_target, axis=-1)
    lo, hi = np.abs(upper - lower) * (1 + 1e-9), (upper + lower) * (1 - 1e-9)
    reach = np.clip(wanted, lo, hi)
    u = np.where(wanted[:, None] > 1e-12, to_target / np.maximum(wanted, 1e-300)[:, None], line)
    poles = np.broadcast_to(np.asarray(poles, dtype=np.float64), a.shape)
    w = poles - np.sum(poles * u, -1, keepdims=True) * u
    w = np.where(np.linalg.norm(w, axis=-1, keepdims=True) > 1e-12, unit(w), unit(bend))
    cos_root = np.clip((upper**2 + reach**2 - lower**2) / (2 * upper * reach), -1.0, 1.0)
    new_b = a + upper[:, None] * (cos_root[:, None] * u + np.sqrt(1 - cos_root**2)[:, None] * w)
    new_c = a + reach[:, None] * u
    # The root turns the old triangle (a, b, c) onto the new one (a straight limb has no
    # triangle: it only swings); the middle then closes it.
    first = arc(b - a, new_b - a)
    axis = unit(new_b - a)
    twist = arc(_plane(quaternion.rotate(first, c - a), axis), _plane(new_c - a, axis))
    straight = np.linalg.norm(bend, axis=-1) <= STRAIGHT * upper
    twist[straight] = [1.0, 0.0, 0.0, 0.0]
    turn_root = quaternion.multiply(twist, first)
    moved_c = new_b + quaternion.rotate(turn_root, c - b)
    turn_middle = quaternion.multiply(arc(moved_c - new_b, new_c - new_b), turn_root)
    rotations = _with_turns(parents, rotations, orientations, chain, turn_root, turn_middle,
                            end_orientations)  # fmt: skip
    reached = kinematics.world_positions(parents, offsets, rotations, translations,
                                         translated)[:, end]  # fmt: skip
    return rotations, reached, np.linalg.norm(reached - targets, axis=-1)


def _plane(v, axis):
    """v without its component along axis (a direction in the plane normal to it)."""
    return v - np.sum(v * axis, -1, keepdims=True) * axis


def _motion_poles(bend, middle_orientation):
    """The direction the middle joint bends to over the whole motion, carried by its orientation
    frame by frame: a knee or an elbow is a hinge, so its bend has one direction in its own frame
    (the frames' directions averaged there, weighted by how bent the limb is). A nearly straight
    limb's own bend swings from frame to frame: followed, the knee would pop."""
    local = quaternion.rotate(quaternion.conjugate(middle_orientation), bend).sum(0)
    if np.linalg.norm(local) < 1e-12:
        local = np.array([0.0, 0.0, 1.0])
    return quaternion.rotate(middle_orientation, unit(local))


def _with_turns(parents, rotations, orientations, chain, turn_root, turn_middle, end_world):
    """Local rotations after the root joint turns by turn_root and the middle by turn_middle
    (world deltas, the middle's including the root's), the end joint set to end_world (or
    kept as it was in the world)."""
    root, middle, end = chain
    if end_world is None:
        end_world = orientations[:, end]
    turned = {j: turn_root for j in path(parents, root, middle)[:-1]}
    turned.update({j: turn_middle for j in path(parents, middle, end)[:-1]})

    def world(j):
        return quaternion.multiply(turned[j], orientations[:, j]) if j in turned else (
            orientations[:, j])  # fmt: skip

    out = rotations.copy()
    out[:, root] = _local(world(root), _parent_orientation(parents, orientations, root))
    out[:, middle] = _local(world(middle), world(parents[middle]))
    out[:, end] = _local(np.asarray(end_world, dtype=np.float64), world(parents[end]))
    return out


class Turns:
    """One frame's pose as the turns of some of its joints move it, for the least-squares solver:
    per ball joint a rotation vector (a turn in the joint's own frame, after its rotation), per
    hinge joint an angle about its axis (in its parent's frame: an elbow or a knee bends only the
    way the motion bends it, hinge_axis). Rows of parameters give poses in one batch.

    parents, local: the skeleton and each joint's offset in its parent's frame at this frame
    (joints, 3); pose: the frame's local rotations (joints, 4); joints: those that may turn (the
    parameters: the ball joints' in the order given, then the hinges'); ends: the joints that
    reach targets; hinges: {joint: axis}; costs: per joint, metres per radian of its turn (the
    pull toward the motion's own pose: the larger, the less the joint moves)."""

    def __init__(self, parents, local, pose, joints, ends, hinges=None, costs=None):
        self.parents, self.local = list(parents), np.asarray(local, dtype=np.float64)
        self.pose = np.asarray(pose, dtype=np.float64)
        self.joints, self.ends, self.hinges = list(joints), list(ends), dict(hinges or {})
        self.balls = [j for j in self.joints if j not in self.hinges]
        self.bent = [j for j in self.joints if j in self.hinges]
        costs = costs or {}
        self.costs = np.concatenate([np.repeat([costs.get(j, 0.0) for j in self.balls], 3),
                                     [costs.get(j, 0.0) for j in self.bent]])  # fmt: skip
        self.size = 3 * len(self.balls) + len(self.bent)
        # every joint on a path from the top to an end, parents first
        self.order = []
        for end in self.ends:
            for j in path(self.parents, _top(self.parents, end), end):
                if j not in self.order:
                    self.order.append(j)

    def rotations(self, x):
        """(n, joints, 4) local rotations for parameter rows x (n, size)."""
        x = np.atleast_2d(x)
        out = np.repeat(self.pose[None], len(x), axis=0)
        nb = len(self.balls)
        turns = quaternion.from_rotation_vector(x[:, : 3 * nb].reshape(len(x), nb, 3))
        out[:, self.balls] = quaternion.multiply(out[:, self.balls], turns)
        angles = x[:, 3 * nb :]
        for k, j in enumerate(self.bent):
            hinge = quaternion.from_rotation_vector(angles[:, k : k + 1] * self.hinges[j])
            out[:, j] = quaternion.multiply(hinge, out[:, j])
        return out

    def ends_at(self, rotations):
        """(n, ends, 3) the ends' positions: forward kinematics along the needed joints only."""
        n = len(rotations)
        pos, ori = {}, {}
        for j in self.order:
            p = self.parents[j]
            if p < 0:
                pos[j] = np.broadcast_to(self.local[j], (n, 3))
                ori[j] = rotations[:, j]
            else:
                pos[j] = pos[p] + quaternion.rotate(ori[p], self.local[j])
                ori[j] = quaternion.multiply(ori[p], rotations[:, j])
        return np.stack([pos[e] for e in self.ends], axis=1)


def _top(parents, joint):
    while parents[joint] >= 0:
        joint = parents[joint]
    return joint


def solve(turns, targets, penalties=None, evaluations=EVALUATIONS):
    """(pose, reached): the frame's pose (joints, 4) whose ends come nearest their targets
    (ends, 3), and where they are. Least squares (scipy's trust-region reflective) over the turns'
    parameters; the residuals: the ends' offsets from their targets, those of penalties(rotations,
    x) (a list of (n, k) arrays: joint limits, a hinge's side) and each turn times its cost. A
    target out of reach ends at the nearest point the chain reaches."""
    from scipy.optimize import least_squares  # here: a session that never solves does not import

    targets = np.asarray(targets, dtype=np.float64).reshape(len(turns.ends), 3)

    def residuals(x):
        x = np.atleast_2d(x)
        rotations = turns.rotations(x)
        parts = [(turns.ends_at(rotations) - targets[None]).reshape(len(x), -1)]
        if penalties is not None:
            parts += penalties(rotations, x)
        parts.append(x * turns.costs[None])
        return np.concatenate(parts, axis=1)

    def jacobian(x):  # forward differences, every column's pose in one batch
        r = residuals(np.vstack([x, x + FINITE_STEP * np.eye(len(x))]))
        return ((r[1:] - r[0]) / FINITE_STEP).T

    solved = least_squares(lambda x: residuals(x)[0], np.zeros(turns.size), jac=jacobian,
                           method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12,
                           max_nfev=evaluations)  # fmt: skip
    pose = turns.rotations(solved.x)
    return pose[0], turns.ends_at(pose)[0]


def hinge_axis(rotations, local, middle, end):
    """The axis (in the middle joint's parent frame) the motion bends the middle joint of a limb
    about: the normal of the plane of the bones before and after it, averaged over the frames
    (weighted by the sine of the bend); None when the limb is straight throughout. rotations:
    (frames, joints, 4); local: (frames, joints, 3) offsets in the parents' frames."""
    upper = unit(local[:, middle])
    lower = quaternion.rotate(rotations[:, middle], unit(local[:, end]))
    normal = np.cross(upper, lower).sum(0)
    size = np.linalg.norm(normal)
    if size < 1e-6 * len(upper) or np.linalg.norm(local[:, middle], axis=-1).min() < 1e-6:
        return None
    return normal / size


def local_offsets(offsets, translated, translations):
    """(frames, joints, 3): each joint's offset from its parent in the parent's frame, the
    translated joints' from the motion's translations (frames, len(translated), 3)."""
    translations = np.asarray(translations, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.float64)
    local = np.broadcast_to(offsets, (translations.shape[0],) + offsets.shape).copy()
    if len(translated):
        local[:, list(translated)] = translations
    return local


def falloff(n_frames, frame, before, after):
    """Weights (n_frames,) of a change made at `frame`: 1 there, a cubic B-spline bump falling to
    0 `before` frames earlier and `after` frames later (0 frames: that side is not touched)."""
    t = np.arange(n_frames, dtype=np.float64) - frame
    span = np.where(t < 0, before, after).astype(np.float64)
    x = np.where(span > 0, 2.0 * t / np.maximum(span, 1e-300), np.where(t == 0, 0.0, 2.0))
    weights = np.nan_to_num(_BUMP(np.clip(x, -2.0, 2.0))) / _BUMP(0.0)
    weights[np.abs(x) >= 2.0] = 0.0
    return weights


def spread(rotations, changed, joints, weights):
    """The rotations with each listed joint's change (changed against rotations, per frame)
    applied in part: weights (frames,) of 0 keep a frame, 1 take its change whole, between them
    slerp from the identity (the same axis, a share of the angle)."""
    out = np.array(rotations, dtype=np.float64)
    joints = list(joints)
    delta = quaternion.multiply(changed[:, joints], quaternion.conjugate(out[:, joints]))
    part = quaternion.power(delta, np.asarray(weights, dtype=np.float64)[:, None, None])
    out[:, joints] = quaternion.canonical(quaternion.multiply(part, out[:, joints]))
    return out


def spread_from(rotations, frame, changed_pose, joints, weights):
    """The rotations with one frame's change (changed_pose: (joints, 4), the pose wanted at
    `frame`) carried to every frame by weights: the same local change, in part, everywhere."""
    rotations = np.asarray(rotations, dtype=np.float64)
    joints = list(joints)
    delta = quaternion.multiply(changed_pose[joints],
                                quaternion.conjugate(rotations[frame, joints]))
    changed = rotations.copy()
    changed[:, joints] = quaternion.multiply(delta[None], rotations[:, joints])
    return spread(rotations, changed, joints, weights)
