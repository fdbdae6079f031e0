"""The real motion data the tests read: where it is, and the CMU length unit."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MOCAP = Path(os.environ.get("MODB_MOCAP", REPO.parent / "shared" / "mocap"))
CMU_UNITS = 0.0254 / 0.45  # metres per CMU ASF length unit (:units length 0.45)


def mocap(*parts: str) -> Path:
    """A path in the shared real data; the test is skipped, saying why, when it is absent."""
    p = MOCAP.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"real motion data not found at {p} (set MODB_MOCAP to the mocap folder)")
    return p
