"""How a source carries itself, read from joint positions so that it means the same on any rig: the
elbows' bend, the upper arms' angle from the trunk and the pelvis's speed over the ground, as
percentiles over every frame of a set of motions.

Why: two capture sources chain into each other only where their poses come within a match
profile's thresholds. Retargeting moves bones onto another skeleton but keeps the performance, so
these figures are the same before and after it; two sources whose ranges do not overlap (arms bent
90 degrees in a power walk, nearly straight in an ordinary one) cannot meet at a seam without a
pose jump larger than either source's own."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from modb.motion import Motion

PERCENTILES = (10, 50, 90)
SIDES = ("left", "right")


@dataclass(frozen=True)
class Measure:
    name: str
    unit: str
    percentiles: tuple[float, float, float]  # PERCENTILES of every frame's value

    def overlaps(self, other: Measure) -> bool:
        """Whether the two p10-p90 ranges share any value."""
        return (
            self.percentiles[0] <= other.percentiles[2]
            and other.percentiles[0] <= self.percentiles[2]
        )

    def text(self) -> str:
        low, mid, high = self.percentiles
        return f"{mid:.3g} {self.unit} ({low:.3g}-{high:.3g})"


def _angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def _per_frame(motion: Motion) -> dict[str, np.ndarray]:
    sk = motion.skeleton
    at = {standard: sk.index(joint) for standard, joint in sk.joint_map.items()}
    p = motion.world_positions()
    trunk_down = p[:, at["pelvis"]] - p[:, at["neck"] if "neck" in at else at["chest"]]
    bend, arm = [], []
    for side in SIDES:
        shoulder, elbow, wrist = (p[:, at[f"{side}_{j}"]] for j in ("shoulder", "elbow", "wrist"))
        bend.append(_angles_deg(elbow - shoulder, wrist - elbow))
        arm.append(_angles_deg(elbow - shoulder, trunk_down))
    ground = p[:, at["pelvis"]][:, [0, 2]]
    speed = np.linalg.norm(np.diff(ground, axis=0), axis=-1) * motion.fps
    return {
        "elbow bend": np.concatenate(bend),
        "upper arm from the trunk": np.concatenate(arm),
        "pelvis speed": speed,
    }


UNITS = {"elbow bend": "deg", "upper arm from the trunk": "deg", "pelvis speed": "m/s"}


def posture(motions: Iterable[Motion]) -> list[Measure]:
    """The measures over every frame of the motions (each needs shoulders, elbows, wrists, pelvis
    and neck or chest in its joint map)."""
    frames: dict[str, list[np.ndarray]] = {name: [] for name in UNITS}
    for motion in motions:
        for name, values in _per_frame(motion).items():
            frames[name].append(values)
    if not frames["pelvis speed"]:
        raise ValueError("no motions to measure")
    return [
        Measure(
            name,
            UNITS[name],
            tuple(float(x) for x in np.percentile(np.concatenate(v), PERCENTILES)),
        )
        for name, v in frames.items()
    ]


def apart(one: list[Measure], other: list[Measure]) -> list[str]:
    """The measures whose p10-p90 ranges do not overlap: what keeps two sources from meeting."""
    return [a.name for a, b in zip(one, other, strict=True) if not a.overlaps(b)]
