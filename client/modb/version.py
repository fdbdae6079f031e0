"""MoDB's one version number: `default_version` in extension/modb.control, read from the source tree
beside this package when it is there (a checkout, an editable install, the build), else the
installed distribution's, which the build took from the same file."""

from __future__ import annotations

import re
from pathlib import Path

CONTROL = Path(__file__).resolve().parents[2] / "extension" / "modb.control"


def _version() -> str:
    try:
        text = CONTROL.read_text()
    except OSError:
        # only an installed wheel gets here; importlib.metadata costs 15 ms otherwise
        from importlib.metadata import version

        return version("modb")
    match = re.search(r"^default_version\s*=\s*'([^']+)'", text, re.MULTILINE)
    if match is None:
        raise RuntimeError(f"no default_version in {CONTROL}")
    return match.group(1)


__version__ = _version()
