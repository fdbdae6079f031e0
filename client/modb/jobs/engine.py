"""The Procrastinate app for a database: its connector (every connection as modb_worker, naming
this process: connection.py) and modb's tasks."""

from __future__ import annotations

import procrastinate

from .connection import as_worker


def job_app(conninfo: str) -> procrastinate.App:
    from .tasks import register  # the tasks import the kernel and numpy: only when an app is made

    app = procrastinate.App(
        connector=procrastinate.PsycopgConnector(
            conninfo=as_worker(conninfo), min_size=1, max_size=4
        )
    )
    register(app)
    return app
