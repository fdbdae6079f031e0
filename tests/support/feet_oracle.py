"""The tests' own measure of feet on the ground (issue 59), on their own forward kinematics (scipy's
rotations) and a contact rule of their own, independent of the one the hold uses (the steps' speed
and height rule) and written apart from modb.synthesis.feet: a toe is on the floor while it is
within 3 cm of the capture's lowest toe (its 0.5th percentile), and what slides is the lower toe.

- sliding: the mean ground speed (m/s, central differences) of the lower toe while on the floor;
- dip: how far the lowest toe goes below the capture's lowest (m);
- clearance: the toes' 95th-percentile height (m);
- pose jumps: per frame step, the largest move of a body joint relative to the pelvis on the ground.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from support import own_kinematics

ON_FLOOR_M = 0.03


class Body:
    """A skeleton's joints the measures read, by the joint map."""

    def __init__(self, parents, offsets, translated, names, joint_map):
        self.parents, self.offsets, self.translated = list(parents), np.asarray(offsets), translated
        at = {k: names.index(v) for k, v in joint_map.items() if v in names}
        self.toes = [at.get(f"{s}_toe", at[f"{s}_ankle"]) for s in ("left", "right")]
        self.pelvis = at["pelvis"]
        body = []
        for j, p in enumerate(self.parents):  # the pelvis and every joint below it
            if j == self.pelvis or p in body:
                body.append(j)
        self.body = body
        self.legs = [j for j in body if any(_descends(self.parents, j, at[f"{s}_hip"])
                                             for s in ("left", "right"))]  # fmt: skip

    @classmethod
    def of(cls, skeleton):
        return cls(skeleton.parents, skeleton.offsets, skeleton.translated, skeleton.names,
                   skeleton.joint_map)  # fmt: skip

    def positions(self, rotations, translations):
        return own_kinematics.world_positions(self.parents, self.offsets, self.translated,
                                              rotations, translations)  # fmt: skip

    def jumps(self, p):
        ground = p[:, self.pelvis] * np.array([1.0, 0.0, 1.0])
        pose = p[:, self.body] - ground[:, None]
        return np.linalg.norm(np.diff(pose, axis=0), axis=-1).max(axis=1)


def _descends(parents, joint, ancestor):
    while joint >= 0:
        if joint == ancestor:
            return True
        joint = parents[joint]
    return False


def lower_toe(body, p, fps):
    """(height, ground speed) of the lower toe at each inner frame."""
    toes = p[:, body.toes]
    lower = np.argmin(toes[:, :, 1], axis=1)[1:-1]
    speed = np.linalg.norm((toes[2:] - toes[:-2])[..., [0, 2]], axis=-1) * fps / 2
    k = np.arange(len(lower))
    return toes[1:-1][k, lower, 1], speed[k, lower]


@dataclass
class Capture:
    floor: float
    sliding: float
    clearance: float
    jump_p99: float
    jump_p999: float

    @classmethod
    def of(cls, body, clips):
        """clips: [(rotations, translations, fps)]."""
        heights, low, speed, jumps = [], [], [], []
        for rotations, translations, fps in clips:
            p = body.positions(rotations, translations)
            heights.append(p[:, body.toes, 1].ravel())
            h, s = lower_toe(body, p, fps)
            low.append(h)
            speed.append(s)
            jumps.append(body.jumps(p))
        heights, low, speed, jumps = (np.concatenate(x) for x in (heights, low, speed, jumps))
        floor = float(np.percentile(heights, 0.5))
        return cls(floor, float(speed[low <= floor + ON_FLOOR_M].mean()),
                   float(np.percentile(heights, 95)), float(np.percentile(jumps, 99)),
                   float(np.percentile(jumps, 99.9)))  # fmt: skip

    def judge(self, body, p, fps):
        low, speed = lower_toe(body, p, fps)
        on = low <= self.floor + ON_FLOOR_M
        jumps = body.jumps(p)
        return {
            "sliding_x": float(speed[on].mean()) / self.sliding,
            "dip_cm": 100 * (self.floor - float(p[:, body.toes, 1].min())),
            "clearance_x": float(np.percentile(p[:, body.toes, 1], 95)) / self.clearance,
            "jump_max_cm": 100 * float(jumps.max()),
            "above_p99": float(np.mean(jumps > self.jump_p99)),
        }


def check_targets(held, unheld, capture, clearance_within=0.15, jump_slack_cm=0.05):
    """Issue 59's targets for a strip with its feet held, against the same strip's unheld figures
    (what the seams alone give) and the capture's. Synthesis from models is given more room where
    its own samples fall short (see test_model_synthesis)."""
    assert held["sliding_x"] <= 1.0, (held, unheld)
    assert held["sliding_x"] < unheld["sliding_x"], (held, unheld)
    assert held["dip_cm"] <= 1.0, (held, unheld)
    assert abs(held["clearance_x"] - 1.0) <= clearance_within, (held, unheld)
    assert held["clearance_x"] >= unheld["clearance_x"] - 0.02, (held, unheld)
    # no pose jump above the capture's p99.9 that the seams had not made already
    worst = max(100 * capture.jump_p999, unheld["jump_max_cm"] + jump_slack_cm)
    assert held["jump_max_cm"] <= worst, (held, unheld, capture)
