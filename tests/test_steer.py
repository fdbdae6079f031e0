"""The avatar's steering toward a new goal (synthesis.steer, issue 62) on real walks (Bandai's BVH,
CMU's ASF/AMC), judged by the tests' own forward kinematics (scipy's rotations): frames before the
steering are unchanged, the last frame is the source's turned rigidly by the angle about the
vertical, the angle is the turn left undone toward the goal and at most the limit, the end
placement is where the steered pelvis ends, and the feet slide no more than the source's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support import own_kinematics
from support.data import mocap
from support.reaction import hips_heading

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.synthesis.placement import Placement
from modb.synthesis.steer import STEER_MAX_DEGREES, steer

FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")


def _walk(name: str):
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    asf = mocap("cmu", "16", "16.asf")
    if not walk.exists() or not asf.exists():
        pytest.skip(f"the shipped capture is not at {mocap()} (../shared/mocap beside the project)")
    if name == "bandai":
        return read_bvh(str(walk))
    return read_amc(str(mocap("cmu", "16", "16_15.amc")), read_asf(str(asf)))


@pytest.fixture(scope="module", params=["bandai", "cmu"])
def snippet(request):
    """About 1.2 s from the middle of a walk."""
    m = _walk(request.param)
    n, first = int(round(1.2 * m.fps)), m.n_frames // 2
    return m, m.rotations[first:first + n].copy(), m.translations[first:first + n].copy()


def positions(motion, rotations, translations) -> np.ndarray:
    sk = motion.skeleton
    return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, rotations,
                                          translations)  # fmt: skip


def ends(motion, p: np.ndarray) -> Placement:
    """The pelvis on the ground at the last frame, facing the hips' way."""
    at = {k: motion.skeleton.index(v) for k, v in motion.skeleton.joint_map.items()}
    pelvis = p[-1, at["pelvis"]] * (1.0, 0.0, 1.0)
    return Placement(tuple(pelvis), float(hips_heading(p[-1], at["left_hip"], at["right_hip"])))


def ground_point(end: Placement, bearing: float, metres: float) -> tuple[float, float]:
    return (end.position[0] + metres * math.sin(end.heading + bearing),
            end.position[2] + metres * math.cos(end.heading + bearing))  # fmt: skip


def slowest_foot_speed(motion, p: np.ndarray) -> np.ndarray:
    """Per frame step, the ground speed (m/s) of the slowest of the feet's ankles and toes."""
    joints = [motion.skeleton.index(motion.skeleton.joint_map[k]) for k in FEET]
    ground = p[:, joints][..., [0, 2]]
    return np.linalg.norm(np.diff(ground, axis=0), axis=-1).min(axis=1) * motion.fps


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_goal_far_aside_turns_the_walk_by_the_limit_rigidly_and_feet_stay(snippet, side):
    motion, rotations, translations = snippet
    before = positions(motion, rotations, translations)
    end = ends(motion, before)
    start = 5
    goal = ground_point(end, side * math.radians(80), 3.0)
    r, t, placed, angle = steer(motion.skeleton, rotations, translations, 0, end, goal, start,
                                motion.fps)  # fmt: skip
    assert angle == pytest.approx(side * math.radians(STEER_MAX_DEGREES))
    assert np.array_equal(r[: start + 1], rotations[: start + 1])
    assert np.array_equal(t[: start + 1], translations[: start + 1])
    after = positions(motion, r, t)
    # the last frame: the source's turned about the vertical by the angle (any pivot)
    turn = Rotation.from_euler("y", angle)
    centre, centre0 = after[-1].mean(axis=0), before[-1].mean(axis=0)
    assert np.abs(after[-1] - centre - turn.apply(before[-1] - centre0)).max() < 1e-9
    # where it now ends: the steered pelvis's ground point, the heading turned by the angle
    pelvis = after[-1, motion.skeleton.index(motion.skeleton.joint_map["pelvis"])]
    assert np.allclose(placed.position, pelvis * (1.0, 0.0, 1.0), atol=1e-9)
    assert placed.heading == pytest.approx(math.remainder(end.heading + angle, math.tau))
    # the feet: the slowest foot point no faster than the source's (within 2 cm/s on average)
    steered, source = slowest_foot_speed(motion, after), slowest_foot_speed(motion, before)
    assert steered[start:].mean() <= source[start:].mean() + 0.02, (steered, source)


def test_the_turn_is_the_one_left_undone_toward_the_goal(snippet):
    motion, rotations, translations = snippet
    end = ends(motion, positions(motion, rotations, translations))
    start = 5
    for wanted in (-10.0, 3.0, 12.0):  # the goal this far off the heading the snippet ends with
        goal = ground_point(end, math.radians(wanted), 40.0)  # far: as seen from anywhere near
        _, _, placed, angle = steer(motion.skeleton, rotations, translations, 0, end, goal, start,
                                    motion.fps)  # fmt: skip
        assert math.degrees(angle) == pytest.approx(wanted, abs=1.0)
        bearing = math.atan2(goal[0] - placed.position[0], goal[1] - placed.position[2])
        assert abs(math.remainder(bearing - placed.heading, math.tau)) < math.radians(1.0)
