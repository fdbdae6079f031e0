"""Steering a snippet chosen for a new goal: the part of the turn toward the goal that the snippet
does not make by its end, up to STEER_MAX_DEGREES, added as a turn of the whole body that eases in
over STEER_SECONDS from a given frame, each frame's share turning about the foot the body stands
on then (the slowest of the feet's ankles and toes), so a planted foot stays where it is.

Why: a snippet of capture chosen toward a goal aside usually starts turning late (the walkers of
the capture turned when they chose to), so the character would answer a click only after most of a
second. Game motion matching corrects the character toward the wanted course the same way. The
avatar steers only the snippet that first serves a new goal; modb.synthesize and the chain after
it keep the paper's rule, placed from where the steered snippet ends.
"""

from __future__ import annotations

import math

import numpy as np

from modb.motion import Skeleton
from modb_kernel import kinematics, quaternion, steps

from .placement import Placement

STEER_MAX_DEGREES = 25.0
STEER_SECONDS = 0.3
FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")


def steering_angle(pivot: np.ndarray, end: Placement, goal: tuple[float, ...]) -> float:
    """The turn (radians) the snippet leaves undone: from where it ends facing to the goal as seen
    from `pivot` (a ground point where steering starts), at most STEER_MAX_DEGREES either way."""
    bearing = math.atan2(goal[0] - pivot[0], goal[-1] - pivot[2])
    shortfall = math.remainder(bearing - end.heading, math.tau)
    limit = math.radians(STEER_MAX_DEGREES)
    return min(max(shortfall, -limit), limit)


def _standing_points(skeleton: Skeleton, rotations: np.ndarray, translations: np.ndarray,
                     fps: float) -> np.ndarray:  # fmt: skip
    """(frames, 3) per frame the ground point of the slowest of the feet's ankles and toes (the
    root's on a skeleton whose joint map names no feet)."""
    sk = skeleton
    joints = [sk.index(sk.joint_map[name]) for name in FEET if name in sk.joint_map] or [0]
    positions = kinematics.world_positions(sk.parents, sk.offsets, rotations, translations,
                                           sk.translated)[:, joints]  # fmt: skip
    speed = np.stack([steps.speeds(positions[:, k], fps) for k in range(len(joints))], axis=1)
    slowest = positions[np.arange(len(positions)), speed.argmin(axis=1)]
    return slowest * np.array([1.0, 0.0, 1.0])


def steer(
    skeleton: Skeleton,
    rotations: np.ndarray,
    translations: np.ndarray,
    root_track: int,
    end: Placement,
    goal: tuple[float, ...],
    start: int,
    fps: float,
) -> tuple[np.ndarray, np.ndarray, Placement, float]:
    """The placed snippet (rotations (F, J, 4), translations (F, T, 3)) turned toward `goal` from
    frame `start` on, the turn easing in (smoothstep) over STEER_SECONDS or by its last frame;
    frames up to `start` unchanged. Returns the frames, where the snippet now ends and the angle
    (radians)."""
    pivots = _standing_points(skeleton, rotations, translations, fps)
    angle = steering_angle(pivots[start], end, goal)
    last = len(rotations) - 1
    if angle == 0.0 or start >= last:
        return rotations, translations, end, 0.0
    n = min(max(1, int(round(STEER_SECONDS * fps))), last - start)
    x = np.clip((np.arange(len(rotations)) - start) / n, 0.0, 1.0)
    turned = angle * x * x * (3.0 - 2.0 * x)
    # frame f shows the source turned by turned[f] and shifted by shift[f]; each frame's share of
    # the turn pivots on where its standing point is shown
    shift = np.zeros((len(rotations), 3))
    for f in range(start + 1, len(rotations)):
        previous = quaternion.about_axis("Y", turned[f - 1])
        pivot = quaternion.rotate(previous, pivots[f]) + shift[f - 1]
        step = quaternion.about_axis("Y", turned[f] - turned[f - 1])
        shift[f] = pivot + quaternion.rotate(step, shift[f - 1] - pivot)
    turn = quaternion.about_axis("Y", turned)
    rotations, translations = rotations.copy(), translations.copy()
    rotations[:, 0] = quaternion.canonical(quaternion.multiply(turn, rotations[:, 0]))
    translations[:, root_track] = quaternion.rotate(turn, translations[:, root_track]) + shift
    ends = quaternion.rotate(turn[last], np.asarray(end.position, dtype=np.float64)) + shift[last]
    heading = math.remainder(end.heading + angle, math.tau)
    return rotations, translations, Placement(tuple(float(v) for v in ends), heading), angle
