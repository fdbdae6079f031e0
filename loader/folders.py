"""Where the loader reads a file's bytes and looks for the files beside it: the disk, or files
handed over by name (a web upload's), which have no folder around them.

Each file's bytes are read once per load: the loader hashes and parses the same bytes.
"""

from __future__ import annotations

import os
from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import BinaryIO, Protocol

SKELETON_SUFFIX = ".asf"


class Folder(Protocol):
    def read(self, path: Path) -> bytes:
        """The file's bytes (OSError when it cannot be read)."""
        ...

    def is_file(self, path: Path) -> bool: ...

    def skeletons_beside(self, path: Path) -> list[Path]:
        """The .asf files beside `path`, sorted."""
        ...

    def identity(self, path: Path) -> Hashable:
        """Equal for two paths of the same file."""
        ...

    def stored_name(self, path: Path) -> str:
        """What the catalogue records as the file's name (clip_versions.source_file)."""
        ...


class Disk:
    def read(self, path: Path) -> bytes:
        return path.read_bytes()

    def is_file(self, path: Path) -> bool:
        return path.is_file()

    def skeletons_beside(self, path: Path) -> list[Path]:
        return sorted(f for f in path.parent.iterdir() if f.suffix.lower() == SKELETON_SUFFIX)

    def identity(self, path: Path) -> Hashable:
        return path.resolve()

    def stored_name(self, path: Path) -> str:
        return os.path.abspath(path)


DISK = Disk()


class NamedFiles:
    """Files given by bare name as open binary files (an upload's spooled files): nothing on the
    disk is looked at, and every name is beside every other."""

    def __init__(self, files: Mapping[str, BinaryIO]):
        self.files = files

    def read(self, path: Path) -> bytes:
        f = self.files.get(str(path))
        if f is None:
            raise FileNotFoundError(2, "not in the upload", str(path))
        f.seek(0)
        return f.read()

    def is_file(self, path: Path) -> bool:
        return str(path) in self.files

    def skeletons_beside(self, path: Path) -> list[Path]:
        return sorted(Path(n) for n in self.files if Path(n).suffix.lower() == SKELETON_SUFFIX)

    def identity(self, path: Path) -> Hashable:
        return str(path)

    def stored_name(self, path: Path) -> str:
        return f"upload:{path.name}"  # where it came from: it has no path
