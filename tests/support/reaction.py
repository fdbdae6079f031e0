"""How soon a walking character answers a new goal: the time from the click to its hips' heading
turning TURNED toward the goal for good (shared by the avatar page's test and
bench/avatar_reaction.py, which read the poses differently)."""

from __future__ import annotations

import numpy as np

TURNED = np.radians(5)


def hips_heading(positions: np.ndarray, left_hip: int, right_hip: int) -> np.ndarray:
    """Where the hips face (radians about +Y, 0: +Z) from world positions (..., joints, 3)."""
    axis = positions[..., left_hip, :] - positions[..., right_hip, :]
    return np.arctan2(-axis[..., 2], axis[..., 0])


def mean_heading(heading: np.ndarray) -> float:
    """The mean of headings (radians) on the circle."""
    return float(np.angle(np.exp(1j * np.asarray(heading)).mean()))


def walks_straight(t: np.ndarray, heading: np.ndarray) -> bool:
    """Whether the heading over the last half second is that of the half second before (within
    3 degrees)."""
    halves = [t > t[-1] - 0.5, (t <= t[-1] - 0.5) & (t > t[-1] - 1.0)]
    a, b = (mean_heading(heading[m]) for m in halves)
    return np.degrees(abs(np.angle(np.exp(1j * (a - b))))) < 3.0


def ahead_and_aside(pelvis: np.ndarray, facing: float, ahead: float, aside: float) -> np.ndarray:
    """The ground point (x, z) `ahead` metres along `facing` from the pelvis and `aside` across."""
    forward = np.array([np.sin(facing), np.cos(facing)])
    across = np.array([np.cos(facing), -np.sin(facing)])
    return pelvis + ahead * forward + aside * across


def turn_reaction(t: np.ndarray, heading: np.ndarray, pelvis: np.ndarray, clicked: float,
                  goal: tuple[float, float]) -> float:  # fmt: skip
    """Seconds from `clicked` to the heading turning TURNED toward `goal` for good (to the last
    pose: a stride's sway turns the hips a few degrees and back, a turn stays); inf when it did not.
    t: seconds per pose; pelvis: (poses, 2) ground x, z. The heading at the click is its mean over
    the second before it (a stride: the sway cancels)."""
    before = (t < clicked) & (t >= clicked - 1.0)
    assert before.sum() >= 10, "the poses of the second before the click were not kept"
    h0 = mean_heading(heading[before])
    where = pelvis[before][-1]
    bearing = np.arctan2(goal[0] - where[0], goal[1] - where[1])
    side = np.sign(np.angle(np.exp(1j * (bearing - h0))))
    toward = side * np.angle(np.exp(1j * (heading - h0)))
    after = np.flatnonzero(t >= clicked)
    turned = [k for k in after if (toward[k:] >= TURNED).all()]
    return float(t[turned[0]] - clicked) if turned else np.inf
