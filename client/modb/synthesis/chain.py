"""The vocabulary of a chain of snippets: the goals it walks toward, the Settings that steer each
selection, the Choice of each snippet (where it was placed and why) and the Frames it plays."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .placement import Placement

Goal = tuple[float, ...]  # world {x, z} or {x, y, z}, metres


class NoContinuation(RuntimeError):
    """The database found nothing to play next (all candidates excluded, or an empty collection)."""


@dataclass
class Settings:
    """What the next selections use; changes apply from the next query on."""

    profile: str = "default"
    collection: str | None = None
    # a transition graph (modb.build_transition_graph): choose among its snippets only
    graph: str | None = None
    arrival_radius: float = 0.5  # metres, pelvis to goal on the ground, checked at snippet ends
    exclude_seconds: float = 2.0  # snippets played this recently are passed as `exclude`
    lead_time: float = 0.0  # seconds before a snippet ends at which the next query is issued
    blend_frames: int = 0  # seam blending over this many frames; 0 plays the snippets as captured
    # SET modb.<knob> for this avatar's session (modb.match_knobs())
    knobs: dict[str, str] = field(default_factory=dict)
    # report each choice's modb.candidates_examined (one more query, after it)
    count_candidates: bool = False

    def session_knobs(self) -> dict[str, str]:
        """The SET modb.<knob> of a session selecting with these settings ('' is the profile's)."""
        return {**self.knobs, "graph": self.graph or ""}

    def __post_init__(self) -> None:
        if not self.arrival_radius > 0:
            raise ValueError(f"arrival_radius must be positive, got {self.arrival_radius}")
        for name in ("exclude_seconds", "lead_time", "blend_frames"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} cannot be negative, got {getattr(self, name)}")


@dataclass(frozen=True)
class Choice:
    """One snippet of the chain, where it was placed and why it was chosen."""

    step: int
    snippet_id: int
    clip_id: int
    version: int
    mirrored: bool
    first_frame: int
    n_frames: int
    fps: float
    start_frame: int  # strip frame of its first frame (the seam frame it stands in for)
    end_frame: int  # strip frame of its last frame
    placement: Placement
    end: Placement
    goal: int  # 1-based position of the goal it served in the goal queue
    target: Goal
    reached: bool  # pelvis within arrival_radius of target at its end
    relax_level: int | None  # None for a start snippet given by the caller
    continuity: float | None
    proximity: float | None
    latency_ms: float | None  # the selection query, as seen by the client
    # how long playback stalled waiting for it (0 when the lead time hid the query)
    waited_ms: float
    candidates: int | None = None  # modb.candidates_examined, with Settings.count_candidates


@dataclass(frozen=True)
class Frame:
    index: int  # frame number in the strip, at the source rate
    step: int  # the chain step it belongs to
    rotations: np.ndarray  # (joints, 4), parent-relative, the root placed in the world
    translations: np.ndarray  # (translated joints, 3) metres


def checked_goal(goal: Goal) -> Goal:
    values = tuple(float(v) for v in goal)
    if len(values) not in (2, 3) or not all(np.isfinite(values)):
        raise ValueError(f"a goal is (x, z) or (x, y, z) in world metres, got {goal!r}")
    return values
