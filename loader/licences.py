"""Under which terms a motion file may be used: what `modb load --licence` states, else the
nearest licence file in the file's folder or one of the folders above it (Bandai's datasets ship a
LICENSE at their top; CMU's files ship none, so their terms are stated by the user). Kept in the
version's meta so that what is made from the clip (retargeted clips, synthesized strips, exports)
can name its sources and their terms.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from .folders import DISK, Folder

LICENCE_FILES = ("LICENSE", "LICENSE.txt", "LICENSE.md", "LICENCE", "LICENCE.txt", "COPYING")
# Folders above the file's own that are looked in: a dataset's data/ or a subject's folder sits a
# level or two below the file that states its terms.
FOLDERS_UP = 3
MAX_TITLE = 200  # characters kept of the licence's first line
HEAD_BYTES = 4096  # what is read of a licence file for its title
LICENCE_KEYS = ("licence", "licence_file")  # what licence_of puts in a version's meta


def _title(raw: bytes) -> str | None:
    """The first non-blank line of the file's start: a licence file's title ("Attribution-
    NonCommercial 4.0 International"); None for an empty or binary file."""
    head = raw[:HEAD_BYTES]
    if b"\0" in head:
        return None
    for line in head.decode("utf-8", "replace").splitlines():
        if line.strip():
            return line.strip()[:MAX_TITLE]
    return None


def licence_of(
    motion_file: Path, folder: Folder, stated: str | None = None
) -> dict[str, Any] | None:
    """{"licence": title, "licence_file": where it was read} for the nearest licence file, or
    {"licence": stated} when the caller states one; None when neither. A licence file that cannot
    be read is passed over (the motion file still loads)."""
    if stated is not None:
        return {"licence": stated.strip()[:MAX_TITLE]}
    # on the disk, the folders above a relative path too; an upload's names have no folders
    here = Path(os.path.abspath(motion_file)).parent if folder is DISK else motion_file.parent
    for directory in [here, *here.parents][: FOLDERS_UP + 1]:
        for name in LICENCE_FILES:
            candidate = directory / name
            try:
                title = _title(folder.read(candidate)) if folder.is_file(candidate) else None
            except OSError:
                continue
            if title:
                return {"licence": title, "licence_file": folder.stored_name(candidate)}
    return None
