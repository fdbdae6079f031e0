"""The Procrastinate app for a database: its connector (every connection as modb_loader:
connection.py) and modb's tasks."""

from __future__ import annotations

import procrastinate

from .connection import as_loader


def job_app(conninfo: str) -> procrastinate.App:
    from .tasks import register  # the tasks import the kernel and numpy: only when an app is made

    app = procrastinate.App(
        connector=procrastinate.PsycopgConnector(
            conninfo=as_loader(conninfo), min_size=1, max_size=4
        )
    )
    register(app)
    return app
