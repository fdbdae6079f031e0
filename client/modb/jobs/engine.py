"""The Procrastinate app for a database: its connector (every connection as modb_loader: workers and
submitters write what the loader role may, never as a superuser) and modb's tasks."""

from __future__ import annotations

import procrastinate
from psycopg.conninfo import conninfo_to_dict, make_conninfo

LOADER_ROLE = "modb_loader"


def as_loader(conninfo: str) -> str:
    """The connection string with the loader role set at connection (the login role must be a
    member of it)."""
    options = conninfo_to_dict(conninfo).get("options") or ""
    return make_conninfo(conninfo, options=f"{options} -c role={LOADER_ROLE}".strip())


def job_app(conninfo: str) -> procrastinate.App:
    from .tasks import register  # the tasks import the kernel and numpy: only when an app is made

    app = procrastinate.App(
        connector=procrastinate.PsycopgConnector(
            conninfo=as_loader(conninfo), min_size=1, max_size=4
        )
    )
    register(app)
    return app
