"""The kernel's inverse kinematics (issue 59) on real rigs (Bandai's BVH, CMU's ASF/AMC), judged by
the test's own forward kinematics (scipy's rotations): reachable targets met within 1 mm, bone
lengths kept, an unreachable target met at the nearest point the limb reaches, the knee bent
the way the motion bends it, the foot's world orientation kept, and a change spread by a falloff
that is 1 at its frame and 0 outside its range."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support import own_kinematics
from support.data import mocap

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb_kernel import ik

RNG = np.random.default_rng(59)


def _rigs():
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    asf = mocap("cmu", "16", "16.asf")
    if not walk.exists() or not asf.exists():
        pytest.skip(f"the shipped capture is not at {mocap()} (../shared/mocap beside the project)")
    cmu = read_amc(str(mocap("cmu", "16", "16_15.amc")), read_asf(str(asf)))
    return {"bandai": read_bvh(str(walk)), "cmu": cmu}


@pytest.fixture(scope="module", params=["bandai", "cmu"])
def motion(request):
    m = _rigs()[request.param]
    return replace(m, rotations=m.rotations[::7], translations=m.translations[::7])  # every 7th


def positions(motion, rotations):
    sk = motion.skeleton
    return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, rotations,
                                          motion.translations)  # fmt: skip


def world_rotations(motion, rotations, joint):
    return own_kinematics.world_rotation(motion.skeleton.parents, rotations, joint)


def leg(motion, side="left"):
    sk = motion.skeleton
    return [sk.index(sk.joint_map[f"{side}_{part}"]) for part in ("hip", "knee", "ankle")]


def bone_lengths(p, joints):
    return np.linalg.norm(p[:, joints[1:]] - p[:, joints[:-1]], axis=-1)


def solve_two_bone(motion, chain, targets, **options):
    sk = motion.skeleton
    return ik.two_bone(sk.parents, sk.offsets, motion.rotations, motion.translations,
                       sk.translated, chain, targets, **options)  # fmt: skip


def test_two_bone_meets_reachable_targets_keeping_bones_foot_and_knee_side(motion):
    chain = leg(motion)
    before = positions(motion, motion.rotations)
    # targets a few cm from the ankle in any direction, drawn a tenth of the way toward the hip
    # (a walking leg is nearly straight: most of them lie within its reach)
    ankle, hip = before[:, chain[2]], before[:, chain[0]]
    targets = ankle + (hip - ankle) * 0.1 + RNG.normal(size=(motion.n_frames, 3)) * 0.05
    rotations, reached, miss = solve_two_bone(motion, chain, targets)
    after = positions(motion, rotations)
    upper_lower = bone_lengths(before, chain)
    room = np.linalg.norm(targets - before[:, chain[0]], axis=-1) < upper_lower.sum(1) * 0.999
    assert room.mean() > 0.8
    assert np.abs(after[room, chain[2]] - targets[room]).max() < 1e-3
    assert np.allclose(after[:, chain[2]], reached, atol=1e-9)
    assert np.abs(miss[room]).max() < 1e-3
    # every bone of the skeleton keeps its length (the leg's and all others)
    sk = motion.skeleton
    kids = [j for j, p in enumerate(sk.parents) if p >= 0]
    parents = [sk.parents[j] for j in kids]
    length = lambda p: np.linalg.norm(p[:, kids] - p[:, parents], axis=-1)  # noqa: E731
    assert np.abs(length(after) - length(before)).max() < 1e-9
    # the foot keeps its world orientation; nothing above the hip moves
    foot_change = (world_rotations(motion, rotations, chain[2])
                   * world_rotations(motion, motion.rotations, chain[2]).inv()).magnitude()
    assert foot_change.max() < 1e-6
    above = [j for j in range(len(sk.parents)) if j not in _subtree(sk.parents, chain[0])]
    assert np.abs(after[:, above] - before[:, above]).max() < 1e-9
    # the knee stays on the side it bent to: the bend direction turns by less than 90 degrees
    assert (_bend(after, chain) * _bend(before, chain)).sum(-1)[room].min() > 0
    # and bends as a hinge: its own rotation changes about the normal of the leg's plane
    knee_old = world_rotations(motion, motion.rotations, chain[1])
    change = own_kinematics.rotations_of(motion.rotations[:, chain[1]]).inv() * \
        own_kinematics.rotations_of(rotations[:, chain[1]])
    a, b, c = (before[:, j] for j in chain)
    normal = knee_old.inv().apply(np.cross(b - a, c - b))
    axis = change.as_rotvec()
    turned = np.linalg.norm(axis, axis=1) > np.radians(1)
    size = np.linalg.norm(axis, axis=1) * np.linalg.norm(normal, axis=1)
    cosine = np.abs((axis * normal).sum(1)) / size
    assert cosine[turned & room].min() > np.cos(np.radians(2))


def _subtree(parents, root):
    out = {root}
    for j, p in enumerate(parents):
        if p in out:
            out.add(j)
    return out


def _bend(p, chain):
    a, b, c = (p[:, j] for j in chain)
    line = (c - a) / np.linalg.norm(c - a, axis=-1, keepdims=True)
    bend = (b - a) - ((b - a) * line).sum(-1, keepdims=True) * line
    return bend / np.linalg.norm(bend, axis=-1, keepdims=True)


def test_two_bone_out_of_reach_ends_at_the_nearest_reachable_point(motion):
    chain = leg(motion, "right")
    before = positions(motion, motion.rotations)
    hip = before[:, chain[0]]
    length = bone_lengths(before, chain).sum(1)
    direction = RNG.normal(size=(motion.n_frames, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    targets = hip + direction * (length * 1.5)[:, None]
    rotations, reached, miss = solve_two_bone(motion, chain, targets)
    after = positions(motion, rotations)
    # the nearest point of the ball the leg reaches: on the line toward the target, at full length
    nearest = hip + direction * length[:, None]
    assert np.abs(after[:, chain[2]] - nearest).max() < 1e-3
    assert np.allclose(miss, length * 0.5, atol=1e-3)


def test_two_bone_takes_a_pole_and_an_end_orientation(motion):
    chain = leg(motion)
    before = positions(motion, motion.rotations)
    targets = before[:, chain[2]] + [0.0, 0.05, 0.03]
    pole = np.array([1.0, 0.0, 0.0])  # the knee to the character's... +X, whatever it was
    turned = Rotation.from_euler("y", 30, degrees=True) * world_rotations(motion, motion.rotations,
                                                                         chain[2])  # fmt: skip
    wxyz = np.roll(turned.as_quat(), 1, axis=1)
    rotations, _, _ = solve_two_bone(motion, chain, targets, poles=pole, end_orientations=wxyz)
    after = positions(motion, rotations)
    assert np.abs(after[:, chain[2]] - targets).max() < 1e-3
    # the middle joint bends toward the pole: its offset from the limb's line points along +X
    assert (_bend(after, chain) @ pole).min() > 0.99
    change = (world_rotations(motion, rotations, chain[2]) * turned.inv()).magnitude()
    assert change.max() < 1e-6


def test_the_chain_solver_meets_targets_along_a_longer_chain(motion):
    sk = motion.skeleton
    chest, wrist = (sk.index(sk.joint_map[n]) for n in ("chest", "left_wrist"))
    joints = ik.path(sk.parents, chest, wrist)[:-1]
    local = ik.local_offsets(sk.offsets, sk.translated, motion.translations)
    before = positions(motion, motion.rotations)
    others = [j for j in range(len(sk.parents)) if j not in joints]
    rng = np.random.default_rng(159)  # its own: the targets do not hang on the tests' order
    for frame in (0, motion.n_frames // 2, motion.n_frames - 1):
        # a target the chain reaches: where the wrist goes when the chain's joints turn at random
        # (up to about 0.3 radians each; scipy's rotations, the tests' own kinematics)
        turned = motion.rotations[frame : frame + 1].copy()
        for j in joints:
            turn = Rotation.from_rotvec(rng.normal(size=3) * 0.15)
            turned[0, j] = np.roll((turn * own_kinematics.rotations_of(turned[0, j])).as_quat(), 1)
        target = own_kinematics.world_positions(
            sk.parents, sk.offsets, sk.translated, turned,
            motion.translations[frame : frame + 1])[0, wrist]  # fmt: skip
        assert np.linalg.norm(target - before[frame, wrist]) > 0.02  # not where it stood
        turns = ik.Turns(sk.parents, local[frame], motion.rotations[frame], joints, [wrist])
        pose, reached = ik.solve(turns, target[None])
        rotations = motion.rotations.copy()
        rotations[frame] = pose
        after = positions(motion, rotations)[frame]
        assert np.linalg.norm(after[wrist] - target) < 1e-3
        assert np.allclose(after[wrist], reached[0], atol=1e-9)
        assert np.array_equal(pose[others], motion.rotations[frame, others])


def test_the_chain_solver_and_two_bone_meet_a_leg_target_bending_the_knee_alike(motion):
    """two_bone is the chain solver's closed form for a limb: on a leg with the knee a hinge,
    both put the ankle on a reachable target, the knee bent to the same side of the limb."""
    sk = motion.skeleton
    hip, knee, ankle = leg(motion)
    local = ik.local_offsets(sk.offsets, sk.translated, motion.translations)
    before = positions(motion, motion.rotations)
    targets = before[:, ankle] + [0.0, 0.1, 0.05]
    closed, _, _ = solve_two_bone(motion, (hip, knee, ankle), targets)
    closed_p = positions(motion, closed)
    axis = ik.hinge_axis(motion.rotations, local, knee, ankle)
    assert axis is not None
    for frame in range(0, motion.n_frames, max(1, motion.n_frames // 6)):
        turns = ik.Turns(sk.parents, local[frame], motion.rotations[frame], [knee, hip],
                         [ankle], {knee: axis})  # fmt: skip
        pose, _ = ik.solve(turns, targets[frame][None])
        rotations = motion.rotations.copy()
        rotations[frame] = pose
        p = positions(motion, rotations)[frame]
        assert np.linalg.norm(p[ankle] - targets[frame]) < 1e-3
        assert np.linalg.norm(closed_p[frame, ankle] - targets[frame]) < 1e-3

        def side(q):  # the knee's offset from the hip-ankle line, as a unit vector
            line = (q[ankle] - q[hip]) / np.linalg.norm(q[ankle] - q[hip])
            off = (q[knee] - q[hip]) - np.dot(q[knee] - q[hip], line) * line
            return off / np.linalg.norm(off)

        assert np.dot(side(p), side(closed_p[frame])) > 0.9, frame


def test_the_falloff_is_a_cubic_b_spline_bump_and_spread_keeps_frames_outside():
    w = ik.falloff(41, 20, 8, 12)
    # the independent cubic B-spline: the uniform cardinal one, (2-|x|)^3/6 - 4(1-|x|)^3_+/6
    def cardinal(x):
        x = abs(x)
        return ((2 - x) ** 3 - 4 * max(0.0, 1 - x) ** 3) / 6 if x < 2 else 0.0

    own = [cardinal(2 * (t - 20) / (8 if t < 20 else 12)) / cardinal(0) for t in range(41)]
    assert np.allclose(w, own, atol=1e-12)
    assert w[20] == 1.0 and w[:13].max() == 0.0 and w[32:].max() == 0.0
    assert np.all(np.diff(w[12:21]) > 0) and np.all(np.diff(w[20:33]) < 0)
    rotations = Rotation.random(41 * 3, random_state=1).as_quat().reshape(41, 3, 4)
    rotations = np.roll(rotations, 1, axis=-1)
    wanted = Rotation.from_rotvec([0.0, 0.6, 0.0]) * own_kinematics.rotations_of(rotations[20, 1])
    pose = rotations[20].copy()
    pose[1] = np.roll(wanted.as_quat(), 1)
    out = ik.spread_from(rotations, 20, pose, [1], w)
    assert np.allclose(np.abs((out[:, [0, 2]] * rotations[:, [0, 2]]).sum(-1)), 1.0)
    assert np.allclose(np.abs((out[w == 0, 1] * rotations[w == 0, 1]).sum(-1)), 1.0)
    rot = own_kinematics.rotations_of
    got = rot(out[:, 1]) * rot(rotations[:, 1]).inv()
    assert np.allclose(got.magnitude(), 0.6 * w, atol=1e-9)
