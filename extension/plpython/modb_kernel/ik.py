"""Inverse kinematics: one solver for the feet, actions and the motion editor.

- two_bone: a limb of two bones (hip-knee-ankle, shoulder-elbow-wrist) reaches a target
  analytically. The limb bends in the plane of its pole: by default the direction the middle
  joint points to in the motion itself (the knee's or the elbow's way kept), or a given world
  direction. The end joint keeps its world orientation (the foot stays as it was turned) unless
  one is given. A target out of reach is met as nearly as the limb can: the end joint on the line
  from the limb's root toward the target, at the limb's full (or least) length.
- ccd: cyclic coordinate descent over a longer chain of joints (the DFKI motion editor's choice):
  each joint, from the end inward, turned so that the end points at the target, until the end is
  within TOLERANCE_M or ITERATIONS rounds have run. The edit scripts' `ik` (pose_edits.py) and the
  actions' arm (reach.py) solve their chains by least squares instead (hinge elbows and knees, joint
  limits), and spread the change with falloff/spread_from below.
- spread: a change made at one frame carried over the frames around it, each joint's change
  weighted by a cubic B-spline bump (1 at the frame, falling smoothly to 0 at the range's ends).

Poses are the kernel's: per frame, a unit quaternion per joint relative to its parent, and local
translations of the joints with position channels (kinematics.world_transforms). Every function
works on many frames at once and returns new rotations; translations never change, so bone
lengths are kept. A chain is given by joint indices, from its root to its end; joints between them
in the hierarchy are carried along.
"""

import numpy as np
from scipy.interpolate import BSpline

from . import kinematics, quaternion

TOLERANCE_M = 1e-4  # CCD stops when the end is this close to its target
ITERATIONS = 256  # CCD's most rounds
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


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300)


def arc(u, v):
    """The shortest rotation taking directions u to v (..., 3); opposite directions turn about an
    axis normal to u."""
    u, v = _unit(u), _unit(v)
    cross = np.cross(u, v)
    dot = np.sum(u * v, axis=-1, keepdims=True)
    q = np.concatenate([1.0 + dot, cross], axis=-1)
    opposite = (1.0 + dot[..., 0]) < 1e-9
    if np.any(opposite):
        other = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        axis = _unit(np.cross(u, other))
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
    line = _unit(c - a)
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
    w = np.where(np.linalg.norm(w, axis=-1, keepdims=True) > 1e-12, _unit(w), _unit(bend))
    cos_root = np.clip((upper**2 + reach**2 - lower**2) / (2 * upper * reach), -1.0, 1.0)
    new_b = a + upper[:, None] * (cos_root[:, None] * u + np.sqrt(1 - cos_root**2)[:, None] * w)
    new_c = a + reach[:, None] * u
    # The root turns the old triangle (a, b, c) onto the new one (a straight limb has no
    # triangle: it only swings); the middle then closes it.
    first = arc(b - a, new_b - a)
    axis = _unit(new_b - a)
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
    return quaternion.rotate(middle_orientation, _unit(local))


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


def ccd(parents, offsets, rotations, translations, translated, chain, targets,
        iterations=ITERATIONS, tolerance=TOLERANCE_M):  # fmt: skip
    """(rotations, reached, miss) as two_bone, for a chain of any length: chain[0] is the first
    joint that may turn, chain[-1] the end that reaches; every joint on the path between them
    turns. The end joint keeps its world orientation."""
    rotations = np.array(rotations, dtype=np.float64)
    joints = path(parents, chain[0], chain[-1])
    positions, orientations = kinematics.world_transforms(parents, offsets, rotations,
                                                          translations, translated)  # fmt: skip
    end_world = orientations[:, joints[-1]].copy()
    base_parent = _parent_orientation(parents, orientations, joints[0]).copy()
    targets = np.broadcast_to(np.asarray(targets, dtype=np.float64), positions[:, 0].shape)
    p = positions[:, joints].copy()  # (frames, chain, 3)
    o = orientations[:, joints].copy()
    for _ in range(iterations):
        if np.all(np.linalg.norm(p[:, -1] - targets, axis=-1) <= tolerance):
            break
        for k in range(len(joints) - 2, -1, -1):
            turn = arc(p[:, -1] - p[:, k], targets - p[:, k])
            below = p[:, k + 1:] - p[:, k:k + 1]
            p[:, k + 1:] = p[:, k:k + 1] + quaternion.rotate(turn[:, None], below)
            o[:, k:] = quaternion.multiply(turn[:, None], o[:, k:])
    out = rotations.copy()
    parent_world = base_parent
    for k, j in enumerate(joints[:-1]):
        out[:, j] = _local(o[:, k], parent_world)
        parent_world = o[:, k]
    out[:, joints[-1]] = _local(end_world, parent_world)
    reached = kinematics.world_positions(parents, offsets, out, translations,
                                         translated)[:, joints[-1]]  # fmt: skip
    return out, reached, np.linalg.norm(reached - targets, axis=-1)


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
