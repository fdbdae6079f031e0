"""Feet on the ground: the kernel's foot hold for a client's skeleton, and how feet meet the
ground, measured the same way on capture and on synthesized strips by a rule of its own (not the
contact rule the hold uses): the toes' heights only.

- sliding: the mean ground speed (m/s, central differences) of the lower toe while it is within
  NEAR_FLOOR_M of the floor, the floor being the capture's lowest toe (its FLOOR_PERCENTILE-th
  percentile, robust to a stray frame);
- toe dip: how far the strip's lowest toe goes below the capture's lowest (m, > 0 below);
- clearance: the toes' 95th-percentile height (swing feet lift: a shuffle keeps it low);
- for a strip, each figure against the capture's (sliding and clearance as ratios).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from modb.motion import Motion, Skeleton
from modb_kernel.foot_hold import FootHold

__all__ = ["FootHold", "Ground", "feet_held", "toe_heights"]

NEAR_FLOOR_M = 0.03
FLOOR_PERCENTILE = 0.5
SIDES = ("left", "right")


def feet_held(skeleton: Skeleton, fps: float) -> FootHold:
    """The kernel's foot hold (modb_kernel.foot_hold) for a skeleton: feed it a strip's pieces."""
    sk = skeleton
    return FootHold(sk.parents, sk.offsets, sk.translated, sk.names, sk.joint_map, fps)


def toe_heights(motion: Motion, positions: np.ndarray | None = None) -> np.ndarray:
    """(frames, 2) world heights of the left and right toes (the ankles on a rig without toes);
    positions: the motion's world positions when already computed."""
    sk = motion.skeleton
    p = motion.world_positions() if positions is None else positions
    return np.stack([p[:, _toe(sk, side), 1] for side in SIDES], axis=1)


def _toe(sk, side: str) -> int:
    name = sk.joint_map.get(f"{side}_toe") or sk.joint_map[f"{side}_ankle"]
    return sk.index(name)


def _lower_toe_speed(motion: Motion, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(height, ground speed) of the lower toe per inner frame."""
    sk = motion.skeleton
    toes = np.stack([p[:, _toe(sk, side)] for side in SIDES], axis=1)  # (frames, 2, 3)
    lower = np.argmin(toes[:, :, 1], axis=1)
    speed = np.linalg.norm((toes[2:] - toes[:-2])[:, :, [0, 2]], axis=-1) * motion.fps / 2
    inner = np.arange(1, len(p) - 1)
    return toes[inner, lower[inner], 1], speed[np.arange(len(inner)), lower[inner]]


@dataclass(frozen=True)
class Ground:
    """The capture's feet: its floor (lowest toe), sliding and clearance."""

    floor_m: float
    sliding_m_s: float
    clearance_m: float

    @classmethod
    def of(cls, motions: list[Motion]) -> Ground:
        heights, pairs = [], []
        for m in motions:
            if m.n_frames < 3:
                continue
            p = m.world_positions()
            heights.append(toe_heights(m, p).ravel())
            pairs.append(_lower_toe_speed(m, p))
        if not heights:
            raise ValueError("no clip of 3 frames or more to measure the capture's feet on")
        floor = float(np.percentile(np.concatenate(heights), FLOOR_PERCENTILE))
        low = np.concatenate([h for h, _ in pairs])
        speed = np.concatenate([s for _, s in pairs])
        near = low <= floor + NEAR_FLOOR_M
        return cls(floor, float(speed[near].mean()),
                   float(np.percentile(np.concatenate(heights), 95)))  # fmt: skip

    def judge(self, motion: Motion) -> dict[str, float]:
        """The strip's figures, and against the capture's."""
        p = motion.world_positions()
        low, speed = _lower_toe_speed(motion, p)
        near = low <= self.floor_m + NEAR_FLOOR_M
        sliding = float(speed[near].mean()) if near.any() else 0.0
        heights = toe_heights(motion, p)
        clearance = float(np.percentile(heights, 95))
        return {
            "sliding_cm_s": 100 * sliding,
            "sliding_x_source": sliding / max(self.sliding_m_s, 1e-9),
            "toe_dip_cm": 100 * (self.floor_m - float(heights.min())),
            "clearance_cm": 100 * clearance,
            "clearance_x_source": clearance / max(self.clearance_m, 1e-9),
        }
