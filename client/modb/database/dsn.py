"""Which database modb talks to.

--dsn, else MODB_DSN, else libpq's environment, else the embedded cluster.
"""

from __future__ import annotations

import os

from .cluster import Cluster

LIBPQ_VARIABLES = ("PGHOST", "PGSERVICE", "PGDATABASE")


def resolve(dsn: str | None) -> tuple[str, str]:
    """(conninfo, where it came from). Starts the embedded cluster when that is the choice."""
    if dsn:
        return dsn, "--dsn"
    if os.environ.get("MODB_DSN"):
        return os.environ["MODB_DSN"], "MODB_DSN"
    if any(os.environ.get(v) for v in LIBPQ_VARIABLES):
        return "", "libpq environment (" + ", ".join(
            v for v in LIBPQ_VARIABLES if os.environ.get(v)
        ) + ")"
    cluster = Cluster.default()
    cluster.start()
    return cluster.dsn(), f"embedded cluster in {cluster.home}"
