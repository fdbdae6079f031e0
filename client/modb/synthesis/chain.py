"""The vocabulary of a chain of snippets: the goals it walks toward, the Settings that steer each
selection, the Choice of each snippet (where it was placed and why) and the Frames it plays."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from modb.validation import checked_number

if TYPE_CHECKING:  # annotations only: `modb`'s command line imports these bounds, and stays light
    import numpy as np

    from .placement import Placement

Goal = tuple[float, ...]  # world {x, z} or {x, y, z}, metres

# The bounds of what a chain may be asked (the command line's options refuse the same).
MAX_SECONDS = 3600.0  # the longest strip synthesize makes: an hour (frames are kept in memory)
MAX_COORDINATE = 1e6  # metres from the origin, for goals and the start position
MAX_ARRIVAL_RADIUS = 100.0  # metres
MAX_EXCLUDE_SECONDS = 3600.0
MAX_LEAD_TIME = 2.0  # seconds: longer than any snippet, the next query would start before it plays
MAX_BLEND_FRAMES = 1000
MAX_ID = 2**63 - 1  # snippet ids are bigint


class NoContinuation(RuntimeError):
    """The database found nothing to play next (all candidates excluded, or an empty collection)."""


@dataclass
class Settings:
    """What the next selections use; changes apply from the next query on."""

    profile: str = "default"
    collection: str | None = None
    # a transition graph (modb.build_transition_graph): choose among its snippets only; None: the
    # newest current one over the data (modb.default_graph), "none": every snippet (the plain rule)
    graph: str | None = None
    arrival_radius: float = 0.5  # metres, pelvis to goal on the ground, checked at snippet ends
    exclude_seconds: float = 2.0  # snippets played this recently are passed as `exclude`
    lead_time: float = 0.0  # seconds before a snippet ends at which the next query is issued
    # the seam treatment: "inertialize" (a decaying offset, inertialize.py), "blend" (the jump
    # spread linearly over blend_frames frames) or "none" (the snippets as captured)
    seam: str = "inertialize"
    blend_frames: int = 0
    # stance feet held from touchdown to lift-off, at the height their snippets hold them
    # (modb_kernel.foot_hold); False shows the seams' treatment alone
    foot_hold: bool = True
    # SET modb.<knob> for this avatar's session (modb.match_knobs())
    knobs: dict[str, str] = field(default_factory=dict)
    # report each choice's modb.candidates_examined (one more query, after it)
    count_candidates: bool = False

    def __setattr__(self, name: str, value) -> None:
        # Checked on every assignment, in __init__ and after it: an avatar reads its settings live.
        if name == "seam" and value not in SEAM_TREATMENTS:
            raise ValueError(f"seam must be one of {', '.join(SEAM_TREATMENTS)}, got {value!r:.50}")
        if name in _SETTINGS_BOUNDS:
            value = checked_number(name, value, *_SETTINGS_BOUNDS[name])
        super().__setattr__(name, value)


SEAM_TREATMENTS = ("inertialize", "blend", "none")

# Settings' numbers: (least, most, least excluded, whole numbers, unit).
_SETTINGS_BOUNDS = {
    "arrival_radius": (0.0, MAX_ARRIVAL_RADIUS, True, False, "metres"),
    "exclude_seconds": (0.0, MAX_EXCLUDE_SECONDS, False, False, "seconds"),
    "lead_time": (0.0, MAX_LEAD_TIME, False, False, "seconds"),
    "blend_frames": (0, MAX_BLEND_FRAMES, False, True, "frames"),
}


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
    # the avatar's turn toward a new goal added to the snippet (synthesis.steer), degrees
    steered_degrees: float = 0.0


@dataclass(frozen=True)
class Frame:
    index: int  # frame number in the strip, at the source rate
    step: int  # the chain step it belongs to
    rotations: np.ndarray  # (joints, 4), parent-relative, the root placed in the world
    translations: np.ndarray  # (translated joints, 3) metres


def checked_goal(goal: Goal) -> Goal:
    """(x, z) or (x, y, z) world metres, each finite and at most MAX_COORDINATE from the origin."""
    try:
        values = tuple(float(v) for v in goal)
    except OverflowError:  # an integer too large for a float
        values = (math.inf,)
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise ValueError(f"a goal is (x, z) or (x, y, z) in world metres, got {goal!r:.200}")
    if not all(abs(v) <= MAX_COORDINATE for v in values):
        raise ValueError(
            f"a goal's coordinates are at most {MAX_COORDINATE:,.0f} metres from the origin, "
            f"got {goal!r:.200}"
        )
    return values


def checked_json_goal(goal: Any) -> Goal:
    """checked_goal() of a goal sent as JSON: only numbers, not "1" or true."""
    if not isinstance(goal, (list, tuple)) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in goal
    ):
        raise ValueError(f"a goal's coordinates are numbers (metres), got {goal!r:.200}")
    return checked_goal(goal)


def checked_position(position) -> tuple[float, float, float]:
    """(x, y, z) world metres, each finite and at most MAX_COORDINATE from the origin."""
    try:
        values = tuple(float(v) for v in position)
    except (TypeError, ValueError, OverflowError):
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in values):
        raise ValueError(
            f"position must be (x, y, z) in world metres, each at most {MAX_COORDINATE:,.0f} from "
            f"the origin, got {position!r:.200}"
        )
    return values


def checked_heading(heading) -> float:
    """A finite angle in radians (0 faces +Z)."""
    ok = isinstance(heading, numbers.Real) and not isinstance(heading, bool)
    if not (ok and math.isfinite(heading)):
        raise ValueError(
            f"heading must be a finite angle in radians (0 faces +Z), got {heading!r:.200}"
        )
    return float(heading)
