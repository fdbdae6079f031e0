"""What a motion file's neighbours say about it, stored in its version's meta.

- X.annotations.json beside X.bvh or X.amc: {"annotations": [{"name", "start", "end"}, ...],
  "tags": ["...", ...]} (frames 0-based, inclusive, as stored; both keys optional).
- Bandai Namco's X.json ({"content": i, "style": j}) with ../cfg/content_label.txt and
  style_label.txt: the clip's tags are the two labels without the dataset prefix (e.g. "walk",
  "chimpira").
- Its terms of use (licences.py): the licence the load states, else the nearest licence file.
"""

from __future__ import annotations

import json
from collections.abc import Hashable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .annotations import AnnotationError, checked, checked_tags
from .errors import MotionFileError
from .folders import DISK, Folder
from .licences import licence_of

SIDECAR = ".annotations.json"


def sidecar_path(motion_file: Path) -> Path:
    return motion_file.with_name(motion_file.stem + SIDECAR)


def _text(raw: bytes) -> str:
    """As Path.read_text reads it: UTF-8, with CRLF and CR read as LF (json's line numbers)."""
    return raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")


def _json(path: Path, folder: Folder) -> Any:
    try:
        return json.loads(_text(folder.read(path)))
    except (OSError, UnicodeDecodeError) as e:
        raise MotionFileError(str(path), None, f"cannot read: {e}") from None
    except json.JSONDecodeError as e:
        raise MotionFileError(str(path), e.lineno, f"not JSON: {e.msg}") from None


@dataclass
class Labels:
    """Bandai Namco's label files, each read once per load: every clip of the dataset names its
    content and style by their numbers in the same two files."""

    _names: dict[tuple[Folder, Hashable], list[str]] = field(default_factory=dict)

    def names(self, path: Path, folder: Folder) -> list[str]:
        key = (folder, folder.identity(path))
        if key not in self._names:
            self._names[key] = _text(folder.read(path)).split()
        return self._names[key]


def _bandai_tags(motion_file: Path, folder: Folder, labels: Labels) -> list[str]:
    numbers = motion_file.with_suffix(".json")  # the clip's label numbers
    cfg = motion_file.parent.parent / "cfg"
    if not (folder.is_file(numbers) and folder.is_file(cfg / "content_label.txt")):
        return []
    ids = _json(numbers, folder)
    if not isinstance(ids, dict):
        return []
    tags = []
    for key in ("content", "style"):
        names = labels.names(cfg / f"{key}_label.txt", folder)
        i = ids.get(key)
        if isinstance(i, int) and 0 <= i < len(names):
            tags.append(names[i].split("_", 1)[-1])
    return tags


def file_meta(
    motion_file: Path,
    n_frames: int,
    folder: Folder = DISK,
    labels: Labels | None = None,
    licence: str | None = None,
) -> dict[str, Any]:
    """The meta the files beside `motion_file` give its new version ({} when none); `labels`: the
    label files this load has read; `licence`: the terms the load states (else a licence file's)."""
    meta: dict[str, Any] = dict(licence_of(motion_file, folder, licence) or {})
    tags = _bandai_tags(motion_file, folder, labels or Labels())
    side = sidecar_path(motion_file)
    if folder.is_file(side):
        given = _json(side, folder)
        if not isinstance(given, dict) or set(given) - {"annotations", "tags"}:
            raise MotionFileError(str(side), None, 'expected {"annotations": [...], "tags": [...]}')
        try:
            if "annotations" in given:
                segments = checked(given["annotations"], n_frames)
                meta["annotations"] = [s.as_json() for s in segments]
            extra = checked_tags(given.get("tags", []))
        except AnnotationError as e:
            raise MotionFileError(str(side), None, str(e)) from None
        tags += [t for t in extra if t not in tags]
    if tags:
        meta["tags"] = tags
    return meta
