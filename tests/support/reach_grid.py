"""Bandai's hand raises, a grid of wrist targets fixed before tuning and the checks of a reach
(issue 63, item 4), judged by the tests' own forward kinematics (scipy): shared by
tests/test_reach.py and bench/reach_grid.py.

Per action (a right, left or both hands raise): clips split into examples (the first TRAIN: their
joint limits, their wrists' peak box) and held-out clips the reach is tried on; the keyframe is the
middle of the plateau where the wrist is highest (within PLATEAU_M of its peak); the targets are
the peak box's centre ("inside") and points DISTANCES beyond the box's face in six directions
(world axes: above, below, front (+Z), back, left (+X), right), and one OUT_OF_REACH_M above the
box (out of reach).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from support import own_kinematics
from support.data import mocap

from modb.loader.bvh import read_bvh

TRAIN = 60
PLATEAU_M = 0.01
DISTANCES = (0.1, 0.2, 0.3)
DIRECTIONS = {"above": (0, 1, 0), "below": (0, -1, 0), "front": (0, 0, 1), "back": (0, 0, -1),
              "left": (1, 0, 0), "right": (-1, 0, 0)}  # fmt: skip
OUT_OF_REACH_M = 1.5
BOX_PERCENTILES = (5, 95)  # the peak box: the examples' peaks between these percentiles per axis
REACH_MARGIN_M = 0.02  # reachable by length: the shoulder within the arm's length less this
SLACK_DEGREES = 10.0
ACTIONS = {"right": "raise-up-right-hand", "left": "raise-up-left-hand",
           "both": "raise-up-both-hands"}  # fmt: skip


def sides_of(action):
    return ("left", "right") if action == "both" else (action,)


def clips(action):
    folder = mocap("bandai-2-dev", "data")
    paths = sorted(folder.glob(f"dataset-2_{ACTIONS[action]}_active_*.bvh"))
    return [read_bvh(str(p)) for p in paths]


def positions(motion, rotations=None):
    sk = motion.skeleton
    rotations = motion.rotations if rotations is None else rotations
    return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, rotations,
                                          motion.translations)  # fmt: skip


def world_rotations(motion, rotations, joint):
    return own_kinematics.world_rotation(motion.skeleton.parents, rotations, joint)


def joint(motion, side, part):
    sk = motion.skeleton
    return sk.index(sk.joint_map[f"{side}_{part}"])


def keyframe(motion, sides):
    """The middle of the plateau where the wrists (their mean height) are highest."""
    p = positions(motion)
    height = np.mean([p[:, joint(motion, s, "wrist"), 1] for s in sides], axis=0)
    plateau = np.flatnonzero(height >= height.max() - PLATEAU_M)
    return int((plateau[0] + plateau[-1]) // 2)


def limits(examples):
    """The examples' joint limits as a motion model stores them (scipy's mean rotation per joint:
    an independent computation of motion_model.joint_limits' form)."""
    rotations = np.concatenate([m.rotations for m in examples])
    mean, degrees = [], []
    for j in range(rotations.shape[1]):
        r = own_kinematics.rotations_of(rotations[:, j])
        m = r.mean()
        q = m.as_quat()
        mean.append([q[3], q[0], q[1], q[2]])
        degrees.append(float(np.degrees((m.inv() * r).magnitude().max())))
    return {"mean": mean, "degrees": degrees}


@dataclass
class Action:
    name: str
    sides: tuple
    examples: list
    held_out: list
    limits: dict
    boxes: dict  # side -> (lo, hi)

    def targets(self, side):
        """[(group, distance, target)]: the grid of one side's wrist."""
        lo, hi = self.boxes[side]
        centre, half = (lo + hi) / 2, (hi - lo) / 2
        out = [("inside", 0.0, centre)]
        for name, d in DIRECTIONS.items():
            d = np.asarray(d, dtype=np.float64)
            for dist in DISTANCES:
                out.append((name, dist, centre + d * (np.abs(d) @ half + dist)))
        out.append(("out of reach", OUT_OF_REACH_M, centre + [0.0, OUT_OF_REACH_M, 0.0]))
        return out


def action(name):
    motions = clips(name)
    examples, held_out = motions[:TRAIN], motions[TRAIN:]
    sides = sides_of(name)
    boxes = {}
    for s in sides:
        peaks = []
        for m in examples:
            p = positions(m)
            peaks.append(p[keyframe(m, sides), joint(m, s, "wrist")])
        lo, hi = np.percentile(peaks, BOX_PERCENTILES, axis=0)
        boxes[s] = (lo, hi)
    return Action(name, sides, examples, held_out, limits(examples), boxes)


def arm_length(motion, side):
    p = positions(motion)[0]
    a, b, c = (p[joint(motion, side, part)] for part in ("shoulder", "elbow", "wrist"))
    return float(np.linalg.norm(b - a) + np.linalg.norm(c - b))


def reachable_by_length(motion, side, frame, target):
    p = positions(motion)[frame]
    shoulder = p[joint(motion, side, "shoulder")]
    return float(np.linalg.norm(target - shoulder)) <= arm_length(motion, side) - REACH_MARGIN_M


def hinge_normal(motion, rotations, side):
    """The elbow's bend normal in the upper arm's frame, summed over the frames (scipy)."""
    p = positions(motion, rotations)
    s, e, w = (joint(motion, side, part) for part in ("shoulder", "elbow", "wrist"))
    upper = world_rotations(motion, rotations, s).inv()
    return upper.apply(np.cross(p[:, e] - p[:, s], p[:, w] - p[:, e]))


def signed_bend_degrees(motion, rotations, side, normal):
    """Per frame the elbow's bend (degrees) about the given normal (in the upper arm's frame):
    negative where it bends the other way."""
    s, e, w = (joint(motion, side, part) for part in ("shoulder", "elbow", "wrist"))
    p = positions(motion, rotations)
    u, v = p[:, e] - p[:, s], p[:, w] - p[:, e]
    upper = world_rotations(motion, rotations, s).inv()
    sine = (upper.apply(np.cross(u, v)) @ normal) / np.linalg.norm(u, axis=1)
    return np.degrees(
        np.arctan2(
            sine / np.linalg.norm(v, axis=1),
            (u * v).sum(1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1),
        )
    )


def limit_excess_degrees(motion, limits, rotations, joints):
    """Per frame and listed joint, its angle from the limits' mean less the examples' range."""
    mean = own_kinematics.rotations_of(np.asarray(limits["mean"]))
    out = []
    for j in joints:
        angle = (mean[j].inv() * own_kinematics.rotations_of(rotations[:, j])).magnitude()
        out.append(np.degrees(angle) - limits["degrees"][j])
    return np.stack(out, axis=1)


def checks(motion, result, sides, frame, targets, limits):
    """The pose checks of one reach, by the tests' own FK: a dict of measurements."""
    sk = motion.skeleton
    before, after = positions(motion), positions(motion, result.rotations)
    out = {}
    out["error"] = {s: float(np.linalg.norm(after[frame, joint(motion, s, "wrist")] - targets[s]))
                    for s in sides}  # fmt: skip
    kids = [j for j, p in enumerate(sk.parents) if p >= 0]
    up = [sk.parents[j] for j in kids]
    length = lambda p: np.linalg.norm(p[:, kids] - p[:, up], axis=-1)  # noqa: E731
    out["bone_change_m"] = float(np.abs(length(after) - length(before)).max())
    moved = [sk.index(n) for n in result.joints]
    own = limit_excess_degrees(motion, limits, motion.rotations, moved)
    new = limit_excess_degrees(motion, limits, result.rotations, moved)
    # past the examples' range: by how much more than the source clip itself was
    out["past_range_deg"] = float(np.max(new - np.maximum(own, 0.0)))
    bend = []
    for s in sides:
        normal = hinge_normal(motion, motion.rotations, s).sum(0)
        normal /= np.linalg.norm(normal)
        own, new_ = (signed_bend_degrees(motion, r, s, normal)
                     for r in (motion.rotations, result.rotations))  # fmt: skip
        bend.append((new_ - np.minimum(own, 0.0)).min())
    # < 0: an elbow bent the other way (past straight) more than the source clip itself
    out["least_bend_deg"] = float(min(bend))
    still = [j for j in range(len(sk.parents)) if j not in moved]
    out["others_equal"] = bool(np.array_equal(result.rotations[:, still],
                                              motion.rotations[:, still]))  # fmt: skip
    jumps = lambda p: np.linalg.norm(np.diff(p, axis=0), axis=-1)  # noqa: E731
    out["jump_bound_m"] = float(np.percentile(jumps(before), 99.9))
    out["jump_m"] = float(jumps(after).max())
    return out
