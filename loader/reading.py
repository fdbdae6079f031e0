"""Turning one source file into a Motion, with the options of the `modb load` call."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from modb.motion import Motion

from .asf import DEFAULT_FPS, AsfSkeleton, read_amc, read_asf
from .bvh import read_bvh
from .sources import SourceFile


@dataclass
class ReadOptions:
    units: str | float = "auto"  # parsed --units
    units_text: str = "auto"  # --units as given, recorded to recognise re-loads
    fps: float | None = None  # AMC only: frames per second (default 120)
    allow_truncated: bool = False  # AMC only: drop an incomplete last frame
    warn: Callable[[str], None] | None = None
    _asf_cache: dict[Path, AsfSkeleton] = field(default_factory=dict)

    def asf(self, path: Path) -> AsfSkeleton:
        key = path.resolve()
        if key not in self._asf_cache:
            self._asf_cache[key] = read_asf(str(path), self.units)
        return self._asf_cache[key]


def read_key(source: SourceFile, options: ReadOptions) -> str:
    """What decides the stored motion besides the file's bytes.

    Equal keys and equal bytes mean there is nothing new.
    """
    if source.asf is None:
        return f"units={options.units_text}"
    return (
        f"units={options.units_text};fps={options.fps or DEFAULT_FPS:g};"
        f"truncated={options.allow_truncated};asf={options.asf(source.asf).sha256}"
    )


def read_source(source: SourceFile, options: ReadOptions) -> Motion:
    if source.asf is not None:
        return read_amc(
            str(source.path),
            options.asf(source.asf),
            options.fps or DEFAULT_FPS,
            options.allow_truncated,
            options.warn,
        )
    return read_bvh(str(source.path), options.units)
