"""Under which terms a motion file may be used: what `modb load --licence` states, else the
nearest licence file in the file's folder or one of the folders above it (Bandai's datasets ship a
LICENSE at their top; CMU's files ship none, so their terms are stated by the user). Kept in the
version's meta so that what is made from the clip (retargeted clips, synthesized strips, exports)
can name its sources and their terms.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .folders import Folder

LICENCE_FILES = ("LICENSE", "LICENSE.txt", "LICENSE.md", "LICENCE", "LICENCE.txt", "COPYING")
# Folders above the file's own that are looked in: a dataset's data/ or a subject's folder sits a
# level or two below the file that states its terms.
FOLDERS_UP = 3
MAX_TITLE = 200  # characters kept of the licence's first line
LICENCE_KEYS = ("licence", "licence_file")  # what licence_of puts in a version's meta


def _title(raw: bytes) -> str | None:
    """The first non-blank line: a licence file's title ("Attribution-NonCommercial 4.0
    International")."""
    for line in raw.decode("utf-8", "replace").splitlines():
        if line.strip():
            return line.strip()[:MAX_TITLE]
    return None


def licence_of(
    motion_file: Path, folder: Folder, stated: str | None = None
) -> dict[str, Any] | None:
    """{"licence": title, "licence_file": where it was read} for the nearest licence file, or
    {"licence": stated} when the caller states one; None when neither."""
    if stated is not None:
        return {"licence": stated.strip()[:MAX_TITLE]}
    here = motion_file.parent
    for directory in [here, *here.parents][: FOLDERS_UP + 1]:
        for name in LICENCE_FILES:
            candidate = directory / name
            if folder.is_file(candidate):
                title = _title(folder.read(candidate))
                if title:
                    return {"licence": title, "licence_file": folder.stored_name(candidate)}
    return None
