"""The `modb` command line, run as a user runs it."""

from __future__ import annotations

import subprocess
import sys


def run_modb(dsn: str, *args: str) -> subprocess.CompletedProcess:
    """The real command line, as a user runs it."""
    return subprocess.run(
        [sys.executable, "-m", "modb.cli", "--dsn", dsn, *map(str, args)],
        capture_output=True,
        text=True,
    )
