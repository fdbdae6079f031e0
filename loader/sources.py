"""Which files a `modb load` call loads, into which collection, and which ASF goes with each AMC."""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from .errors import MotionFileError
from .folders import DISK, SKELETON_SUFFIX, Folder, NamedFiles

MOTION_SUFFIXES = (".bvh", ".amc")


@dataclass
class SourceFile:
    path: Path
    collection: str
    asf: Path | None = None  # the skeleton of an AMC file
    folder: Folder = DISK  # where it and the files beside it are read from


def _walk(directory: Path) -> Iterable[Path]:
    for root, dirs, files in os.walk(directory):
        dirs.sort()
        for name in sorted(files):
            yield Path(root) / name


def find_sources(
    paths: Iterable[str], collection: str | None, asf: str | None = None
) -> list[SourceFile]:
    """Motion files under the given paths (recursively, sorted), each AMC paired with an ASF.

    A directory loads into a collection named after it (or --collection), its
    subdirectories into child collections; a single file loads into a collection
    named after its directory (or --collection). ASF files are skeletons: they pair,
    they are not clips. Two files that would become the same clip are refused.
    """
    sources: list[SourceFile] = []
    named_asf: list[Path] = []
    for given in paths:
        p = Path(given)
        if p.is_dir():
            base = collection or p.resolve().name
            for f in _walk(p):
                if f.suffix.lower() in MOTION_SUFFIXES:
                    rel = f.parent.relative_to(p)
                    sources.append(SourceFile(f, "/".join((base, *rel.parts))))
        elif p.is_file():
            suffix = p.suffix.lower()
            if suffix == SKELETON_SUFFIX:
                named_asf.append(p)
            elif suffix in MOTION_SUFFIXES:
                sources.append(SourceFile(p, collection or p.resolve().parent.name))
            else:
                raise MotionFileError(
                    str(p),
                    None,
                    f"unsupported file type {p.suffix!r}",
                    "modb load reads .bvh, and .amc with its .asf",
                )
        else:
            raise MotionFileError(str(p), None, "no such file or directory")
    _refuse_one_clip_twice(sources, DISK)
    forced = Path(asf) if asf else None
    if forced is not None and not forced.is_file():
        raise MotionFileError(str(forced), None, "no such ASF file (--asf)")
    for source in sources:
        if source.path.suffix.lower() == ".amc":
            source.asf = forced or pair_asf(
                source.path, DISK.skeletons_beside(source.path), named_asf
            )
    return sources


def named_sources(files: NamedFiles, collection: str) -> list[SourceFile]:
    """The motion files among `files` (in their order), each AMC paired with an ASF among them, as
    find_sources pairs and checks the same files given one by one from a folder of their own."""
    names = [Path(n) for n in files.files]
    sources = [
        SourceFile(n, collection, folder=files)
        for n in names
        if n.suffix.lower() in MOTION_SUFFIXES
    ]
    _refuse_one_clip_twice(sources, files)
    skeletons = [n for n in names if n.suffix.lower() == SKELETON_SUFFIX]
    for source in sources:
        if source.path.suffix.lower() == ".amc":
            source.asf = pair_asf(source.path, files.skeletons_beside(source.path), skeletons)
    return sources


def _refuse_one_clip_twice(sources: list[SourceFile], folder: Folder) -> None:
    seen: dict[tuple[str, str], Path] = {}
    for source in sources:
        key = (source.collection, source.path.stem)
        if key in seen and folder.identity(seen[key]) != folder.identity(source.path):
            raise MotionFileError(
                str(source.path),
                None,
                f"{seen[key]} and this file would both become clip {key[0]}/{key[1]}",
                "load them into different collections (--collection)",
            )
        seen[key] = source.path


def pair_asf(amc: Path, beside: list[Path], named: list[Path]) -> Path:
    """The single .asf beside the AMC, else S.asf for S_NN.amc, else the one .asf in the call."""
    if len(beside) == 1:
        return beside[0]
    subject = re.match(r"^(.+?)_\d+$", amc.stem)
    if subject:
        match = [f for f in beside if f.stem == subject.group(1)]
        if len(match) == 1:
            return match[0]
    if len(named) == 1:
        return named[0]
    found = ", ".join(f.name for f in beside) or "none"
    raise MotionFileError(
        str(amc),
        None,
        f"cannot tell which ASF skeleton goes with this AMC (.asf files beside it: {found}; "
        f"named in the call: {len(named)})",
        "pass --asf FILE, or name exactly one .asf file with it",
    )
