"""Annotation segments: named frame ranges of a clip version (meta "annotations": [{"name", "start",
"end", "keyframes", "auto"}], frames 0-based and inclusive, as modb.annotations_ok checks them).
`keyframes` (frames inside the segment: a step's two contacts) and `auto` (true: found by
modb.annotate_steps, which replaces such segments when it runs again) are optional."""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass
from typing import Any

NAME = re.compile(r"^[^\x00-\x1f,!:]{1,64}$")  # no control characters; , ! : separate and negate
SEGMENT = re.compile(r"^(?P<name>[^:]+):(?P<start>\d+)-(?P<end>\d+)$")


class AnnotationError(ValueError):
    pass


@dataclass(frozen=True, order=True)
class Segment:
    start: int
    end: int
    name: str
    keyframes: tuple[int, ...] = ()
    auto: bool = False

    def as_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "start": self.start, "end": self.end}
        if self.keyframes:
            out["keyframes"] = list(self.keyframes)
        if self.auto:
            out["auto"] = True
        return out


def parse_segment(text: str) -> Segment:
    """NAME:START-END (frames, 0-based, inclusive), as `modb annotate --segment` takes it."""
    m = SEGMENT.match(text.strip())
    if not m:
        raise AnnotationError(
            f"a segment is NAME:START-END (frames, e.g. walk:0-120), got {text!r:.80}"
        )
    return Segment(int(m["start"]), int(m["end"]), m["name"].strip())


def segments_of(meta: dict[str, Any]) -> list[Segment]:
    return sorted(
        Segment(int(a["start"]), int(a["end"]), str(a["name"]),
                tuple(int(k) for k in a.get("keyframes", ())), a.get("auto") is True)
        for a in meta.get("annotations", [])
    )  # fmt: skip


def checked(segments: list[Any], n_frames: int) -> list[Segment]:
    """Segments from JSON objects or Segment values, each checked, sorted by start; the error names
    the segment (its index in the list given) and what is wrong."""
    if not isinstance(segments, list):
        raise AnnotationError("annotations is a list of {name, start, end} segments")
    out = []
    for i, seg in enumerate(segments):
        if isinstance(seg, Segment):
            seg = asdict(seg)
        if not isinstance(seg, dict) or set(seg) - {"name", "start", "end", "keyframes", "auto"}:
            raise AnnotationError(
                f"segment {i}: an object with name, start and end (and keyframes, auto), "
                f"got {seg!r:.80}"
            )
        name, start, end = seg.get("name"), seg.get("start"), seg.get("end")
        if not isinstance(name, str) or not NAME.match(name):
            raise AnnotationError(
                f"segment {i}: a name is 1 to 64 characters without control characters, ',', '!' "
                f"or ':', got {name!r:.80}"
            )
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in (start, end)):
            raise AnnotationError(f"segment {i} ({name}): start and end are whole frame numbers")
        if not 0 <= start <= end < n_frames:
            raise AnnotationError(
                f"segment {i} ({name}): frames {start}-{end} do not lie within 0-{n_frames - 1} "
                f"with start <= end"
            )
        keyframes = seg.get("keyframes", ())
        if not isinstance(keyframes, (list, tuple)) or not all(
            isinstance(k, int) and not isinstance(k, bool) and start <= k <= end for k in keyframes
        ):
            raise AnnotationError(
                f"segment {i} ({name}): keyframes are frames within {start}-{end}, "
                f"got {keyframes!r:.80}"
            )
        auto = seg.get("auto", False)
        if not isinstance(auto, bool):
            raise AnnotationError(f"segment {i} ({name}): auto is true or false, got {auto!r:.20}")
        out.append(Segment(start, end, name, tuple(keyframes), auto))
    return sorted(out)


def checked_tags(tags: Any) -> list[str]:
    """Tags: a list of strings."""
    if not (isinstance(tags, list) and all(isinstance(t, str) for t in tags)):
        raise AnnotationError("tags is a list of strings")
    return tags


def with_segments(meta: dict[str, Any], segments: list[Segment]) -> dict[str, Any]:
    """meta with its annotations replaced (the key dropped when there are none)."""
    out = {k: v for k, v in meta.items() if k != "annotations"}
    if segments:
        out["annotations"] = [s.as_json() for s in sorted(segments)]
    return out
