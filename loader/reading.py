"""Turning one source file into a Motion, with the options of the `modb load` call."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from pathlib import Path

from modb.motion import Motion

from .asf import DEFAULT_FPS, AsfSkeleton, parse_amc, parse_asf
from .bvh import parse_bvh
from .folders import DISK, Folder
from .sidecars import Labels
from .sources import SourceFile


@dataclass
class ReadOptions:
    units: str | float = "auto"  # parsed --units
    units_text: str = "auto"  # --units as given, recorded to recognise re-loads
    fps: float | None = None  # AMC only: frames per second (default 120)
    allow_truncated: bool = False  # AMC only: drop an incomplete last frame
    warn: Callable[[str], None] | None = None
    labels: Labels = field(default_factory=Labels)  # the dataset's label files, read once a load
    licence: str | None = None  # --licence: the terms of every file of the load
    _asf_cache: dict[tuple[Folder, Hashable], AsfSkeleton] = field(default_factory=dict)

    def asf(self, path: Path, folder: Folder = DISK) -> AsfSkeleton:
        """The skeleton file, read and parsed once per load however many AMC files share it."""
        key = (folder, folder.identity(path))
        if key not in self._asf_cache:
            raw = folder.read(path)
            self._asf_cache[key] = parse_asf(raw, str(path), self.units, folder.stored_name(path))
        return self._asf_cache[key]


def read_key(source: SourceFile, options: ReadOptions) -> str:
    """What decides the stored motion besides the file's bytes.

    Equal keys and equal bytes mean there is nothing new.
    """
    if source.asf is None:
        return f"units={options.units_text}"
    return (
        f"units={options.units_text};fps={options.fps or DEFAULT_FPS:g};"
        f"truncated={options.allow_truncated};asf={options.asf(source.asf, source.folder).sha256}"
    )


def read_source(source: SourceFile, options: ReadOptions, raw: bytes | None = None) -> Motion:
    """Parse the file from `raw`, its bytes when the caller has read them (to hash them), else
    from its folder."""
    if raw is None:
        raw = source.folder.read(source.path)
    stored_as = source.folder.stored_name(source.path)
    if source.asf is not None:
        return parse_amc(
            raw,
            str(source.path),
            options.asf(source.asf, source.folder),
            options.fps or DEFAULT_FPS,
            options.allow_truncated,
            options.warn,
            stored_as,
        )
    return parse_bvh(raw, str(source.path), options.units, stored_as)
