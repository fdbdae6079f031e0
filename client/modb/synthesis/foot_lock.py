"""Foot locking: a clean-up of a synthesized strip that keeps a standing foot where it stands.

A seam joins two takes whose feet slide against each other, and inertialization (the default seam
treatment) moves the body back onto the new take over a few frames: a foot that stands through the
seam slides with it. Here each foot, while it is down (its ankle, else its toe, within
quality.CONTACT_HEIGHT_M of its lowest, whatever its speed), is held where it stood when it
touched down: a horizontal offset from the strip's foot to the held point, reached by two-bone IK
on the hip and knee, the foot's world orientation kept. When the foot lifts (or the offset would
pass UNLOCK_DISTANCE, more than the leg can give without a visible stretch), the offset decays like
an inertialized seam (critically damped, the same half-life), so nothing jumps: a hold starts where
the foot is shown, and ends moving as it moved.

Measured (bench/seam_treatments.py: three seeded courses each, against inertialization alone; foot
skating as quality.foot_skating defines it): on Bandai's locomotion (60 s), 32.5 -> 27.9 cm/s (the
sources: 24.3), seams with r > 1 and seam r p99 unchanged (2.2%, 1.11), worst pose jump 11.4 ->
11.5 cm; on CMU 131 (30 s, 120 fps), 17.8 -> 11.6 cm/s (sources 12.2), seams with r > 1 unchanged
(15.8%), r p99 1.46 -> 1.44, worst pose jump unchanged (7.7 cm). Tried and measured worse: letting a
hold that went too far go at once (the foot slid back while down: Bandai 32.5 -> 32.4 only); holds
that may go further (0.15 m) or a quicker catch-up (half-life 0.025 s) raise the share of rough
seams; a bend axis taken frame by frame from a nearly straight leg popped the knee (worst pose jump
on CMU 7.7 -> 16.3 cm).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from modb.motion import Motion
from modb_kernel import kinematics, quaternion

from .inertialize import HALFLIFE_SECONDS, decay
from .quality import near_lowest

UNLOCK_DISTANCE = 0.1  # metres: a held foot this far from the strip's foot is let go
# Of the leg's length: a hold that needs a straighter leg is let go (a straight knee pops).
REACH = 0.97
HELD = 1e-4  # metres: a smaller offset leaves the leg as it is
SIDES = ("left", "right")


def lock_feet(motion: Motion) -> Motion:
    """The motion with each standing foot held (the module's docstring says how)."""
    sk = motion.skeleton
    if motion.n_frames < 3:
        return motion
    positions, orientations = kinematics.world_transforms(
        sk.parents, sk.offsets, motion.rotations, motion.translations, sk.translated
    )
    rotations = motion.rotations.copy()
    for side in SIDES:
        hip, knee, ankle, toe = (
            sk.index(sk.joint_map[f"{side}_{part}"]) for part in ("hip", "knee", "ankle", "toe")
        )
        # (Letting a hold ask for a leg as straight as the strip's own, not REACH of its length,
        # held Bandai's feet no better and raised CMU's rough seams 15.8 -> 16.4%.)
        reach = REACH * (
            np.linalg.norm(positions[:, knee] - positions[:, hip], axis=-1)
            + np.linalg.norm(positions[:, ankle] - positions[:, knee], axis=-1)
        )
        offsets = held_offsets(
            positions[:, ankle], positions[:, toe], motion.fps, positions[:, hip], reach
        )
        moved = np.flatnonzero(np.linalg.norm(offsets, axis=-1) > HELD)
        if len(moved):
            leg = (hip, knee, ankle)
            hinge = _knee_hinge(positions, orientations, leg)
            _reach(sk.parents, positions, orientations, rotations, leg, hinge, offsets, moved)
    return replace(motion, rotations=rotations)


def held_offsets(
    ankle: np.ndarray, toe: np.ndarray, fps: float, hip: np.ndarray, reach: np.ndarray
) -> np.ndarray:
    """Per frame, the horizontal offset (metres) from the strip's ankle to where the held foot's
    ankle goes: the ankle held while it stands, else the toe (the foot rolls over it) while it
    does, as long as the offset is within UNLOCK_DISTANCE and the ankle within `reach` of the
    hip. A hold that would go further keeps its offset until the foot lifts (the foot moves as
    the strip's, sliding no more than it); one that would straighten the leg eases back at once;
    a lifted foot's offset decays."""
    # Down: near its lowest, whatever its speed (quality.foot_skating also asks it to be still
    # vertically; a sliding foot is what to hold).
    pivots = np.where(near_lowest(ankle[:, 1]), 0, np.where(near_lowest(toe[:, 1]), 1, -1))
    joints = (ankle, toe)
    offsets = np.zeros_like(ankle)
    offset = np.zeros(3)
    velocity = np.zeros(3)
    held = None  # (pivot, the point it is held at)
    let_go = False  # a hold that went too far: the foot moves as the strip's until it lifts
    released = None  # (frame, offset, velocity) when the last hold ended
    for t, pivot in enumerate(pivots):
        if pivot >= 0 and not let_go:
            shown = joints[pivot][t] * (1.0, 0.0, 1.0)
            if held is None or held[0] != pivot:
                held = (pivot, shown + offset)  # from where the foot is shown: no jump
            wanted = held[1] - shown
            within = np.linalg.norm(ankle[t] + wanted - hip[t]) <= reach[t]
            if np.linalg.norm(wanted) <= UNLOCK_DISTANCE and within:
                velocity = (wanted - offset) * fps
                offset = wanted
                released = None
                offsets[t] = offset
                continue
            if within:  # too far: let go till it lifts; a leg too straight: ease back at once
                let_go, velocity = True, np.zeros(3)
            else:
                pivot = -1
        if pivot >= 0:  # let go while down: the offset stays, the foot slides as the strip's
            held, released = None, None
            offsets[t] = offset
            continue
        held, let_go = None, False
        if released is None:
            released = (t - 1, offset, velocity)
        start, offset0, velocity0 = released
        offset = decay(offset0, velocity0, np.array([(t - start) / fps]), HALFLIFE_SECONDS)[0]
        offsets[t] = offset
    return offsets


def _knee_hinge(positions, orientations, leg) -> np.ndarray:
    """The axis the knee bends about, in the knee's frame: the normal of the leg's plane, averaged
    over the frames weighted by how bent the leg is. (A straight leg has no plane of its own: taken
    frame by frame, its normal swings and the knee pops.)"""
    hip, knee, ankle = (positions[:, j] for j in leg)
    normal = np.cross(ankle - hip, knee - hip)
    return _unit(quaternion.rotate(quaternion.conjugate(orientations[:, leg[1]]), normal).sum(0))


def _reach(parents, positions, orientations, rotations, chain, hinge, offsets, frames) -> None:
    """Two-bone IK in place on `rotations`: in `frames`, hip and knee turned about the knee's
    hinge so the ankle reaches its position plus `offsets`, the ankle's world orientation kept
    (a target beyond the leg's length, which only a decaying offset asks for, falls short)."""
    hip, knee, ankle = chain
    a, b, c = (positions[frames, j] for j in chain)
    target = c + offsets[frames]
    upper, lower = np.linalg.norm(b - a, axis=-1), np.linalg.norm(c - b, axis=-1)
    reach = np.clip(np.linalg.norm(target - a, axis=-1), 1e-6, (upper + lower) * (1 - 1e-6))

    def angle(u, v):
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        v = v / np.linalg.norm(v, axis=-1, keepdims=True)
        return np.arccos(np.clip((u * v).sum(-1), -1.0, 1.0))

    def law_of_cosines(x, y, opposite):
        return np.arccos(np.clip((x * x + y * y - opposite * opposite) / (2 * x * y), -1.0, 1.0))

    # Bend about the knee's hinge: hip angle and knee angle to those of a leg reaching `reach`.
    bend_axis = quaternion.rotate(orientations[frames, knee], hinge)
    hip_turn = law_of_cosines(upper, reach, lower) - angle(c - a, b - a)
    knee_turn = law_of_cosines(upper, lower, reach) - angle(a - b, c - b)
    hip_bend = quaternion.from_rotation_vector(bend_axis * hip_turn[:, None])
    knee_bend = quaternion.multiply(
        hip_bend, quaternion.from_rotation_vector(bend_axis * knee_turn[:, None])
    )
    # Then swing the whole leg from where the bent ankle is to the target (the hinge need not be
    # normal to the leg's plane: a three-channel knee bends a little out of it).
    bent = a + quaternion.rotate(hip_bend, b - a) + quaternion.rotate(knee_bend, c - b)
    swing_axis = _unit(np.cross(bent - a, target - a))
    swing = quaternion.from_rotation_vector(swing_axis * angle(bent - a, target - a)[:, None])
    hip_delta = quaternion.multiply(swing, hip_bend)
    knee_delta = quaternion.multiply(swing, knee_bend)
    # New world orientations, then back to local ones (each joint's parent turned as it is).
    hip_world = quaternion.multiply(hip_delta, orientations[frames, hip])
    knee_world = quaternion.multiply(knee_delta, orientations[frames, knee])
    for joint, world, parent_delta in (
        (hip, hip_world, None),
        (knee, knee_world, hip_delta),
        (ankle, orientations[frames, ankle], knee_delta),
    ):
        parent = orientations[frames, parents[joint]]
        if parent_delta is not None:
            parent = quaternion.multiply(parent_delta, parent)
        rotations[frames, joint] = quaternion.canonical(
            quaternion.multiply(quaternion.conjugate(parent), world)
        )


def _unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors; a zero vector (a straight leg, no swing) becomes any axis with no turn."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-12, v / np.maximum(n, 1e-300), np.array([1.0, 0.0, 0.0]))
