"""What a loader accepts; outside these a file is damaged, or read with the wrong options, and is
refused with its line instead of being stored (or refused later by the database). Plain constants
(no numpy), so the command line can check its options against them before loading anything."""

from __future__ import annotations

FPS_RANGE = (1.0, 1000.0)  # frames per second, inclusive (real capture: 24 to a few hundred)
MAX_LENGTH_M = 1e6  # metres, for any offset or translation (translations are stored as float32)
MAX_JOINT_DEPTH = 256  # joints on the path from the root (which counts 1) to the deepest joint;
# a human skeleton with fingers is about 15 deep
FPS_RANGE_TEXT = f"{FPS_RANGE[0]:g} to {FPS_RANGE[1]:,g} fps"


def fps_in_range(fps: float) -> bool:
    """Whether a frame rate is within FPS_RANGE (False for nan)."""
    return FPS_RANGE[0] <= fps <= FPS_RANGE[1]
