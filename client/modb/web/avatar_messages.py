"""Avatar mode's messages to the page: a frame to show, a selection with the panel's readouts."""

from __future__ import annotations

import base64
from typing import Any

import numpy as np

from modb.motion import Motion
from modb.provenance import Origin, credits

from .downloads import FORMATS, motion_bytes
from modb.synthesis.avatar import Choice, Frame

# Late by less than this, playback catches up (frames sent at once: the stream keeps the clip's
# rate); later, it goes on from now (no burst after a stall).
CATCH_UP_SECONDS = 0.25


def sending_time(due: float, now: float) -> float:
    """When a frame due at `due` (monotonic seconds) goes: then, or from now after a stall."""
    return max(due, now - CATCH_UP_SECONDS)


RECENT = 50  # the readouts summarise the last this many selections


def readout(choices: list[Choice]) -> dict[str, Any]:
    """The panel's live figures over the last RECENT selections (not the start: it has no seam)."""
    recent = [c for c in choices[-RECENT:] if c.latency_ms is not None]
    latency = np.array([c.latency_ms for c in recent])
    seams = np.array([c.continuity for c in recent if c.continuity is not None])
    last = choices[-1]
    return {
        "selections": len(recent),
        "latency_p50_ms": float(np.percentile(latency, 50)) if len(latency) else None,
        "latency_p99_ms": float(np.percentile(latency, 99)) if len(latency) else None,
        "candidates": last.candidates,
        "relax_level": last.relax_level,
        "relaxed_share": float(np.mean([c.relax_level > 0 for c in recent])) if recent else None,
        "seam_ratio_median": float(np.median(seams)) if len(seams) else None,
        "seam_ratio_max": float(seams.max()) if len(seams) else None,
        # r > 1: past the thresholds
        "seam_rough_share": float(np.mean(seams > 1.0)) if len(seams) else None,
    }


def choice_message(
    choice: Choice,
    course: tuple[list, int, bool],
    choices: list[Choice],
    node: str | None = None,
    origin: Origin | None = None,
) -> dict[str, Any]:
    return {
        "type": "choice",
        "node": node,  # the database server that chose it: a standby's name, or "primary"
        # the collection its motion was loaded into (followed back through retargeting), its terms
        "source": origin and {"collection": origin.collection, "licence": origin.licence},
        "step": choice.step,
        "snippet_id": choice.snippet_id,
        "clip_id": choice.clip_id,
        "mirrored": choice.mirrored,
        "fps": choice.fps,
        "start_frame": choice.start_frame,
        "end_frame": choice.end_frame,
        "target": choice.target,
        "reached": choice.reached,
        "relax_level": choice.relax_level,
        "continuity": choice.continuity,
        "latency_ms": choice.latency_ms,
        "waited_ms": choice.waited_ms,
        "candidates": choice.candidates,
        "steered_degrees": choice.steered_degrees,
        "end": {"position": choice.end.position, "heading": choice.end.heading},
        "goals": course[0],
        "goal_index": course[1],
        "readout": readout(choices),
    }


def frame_message(frame: Frame) -> dict[str, Any]:
    return {
        "type": "frame",
        "index": frame.index,
        "step": frame.step,
        "rotations": np.round(frame.rotations, 6).tolist(),
        "translations": np.round(frame.translations, 5).tolist(),
    }


def file_message(walk: Motion, fmt: str, sources: list[dict]) -> dict[str, Any]:
    """A download of the walk (root motion on) as the page saves it: BVH or glTF, its sources
    named inside (a glTF file's asset.copyright) and for the page to show."""
    if sources:
        walk.meta["sources"] = sources
    media, extension = FORMATS[fmt]
    return {
        "type": "file",
        "name": f"walk.{extension}",
        "media_type": media,
        "data": base64.b64encode(motion_bytes(walk, fmt)).decode(),
        "seconds": (walk.n_frames - 1) / walk.fps,
        "sources": credits(sources),
    }
