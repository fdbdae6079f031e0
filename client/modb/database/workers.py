"""The embedded database's job workers (`modb db start --workers N`, stopped by `modb db stop`): one
`modb worker --concurrency N` in its own session, logging to home/workers.log, connected as the web
role (a member of modb_loader, not a superuser)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from psycopg.conninfo import make_conninfo

from .cluster import WRITER_ROLE, Cluster

STOP_WAIT_S = 60  # a running job finishes its current step first


def _pidfile(cluster: Cluster):
    return cluster.home / "workers.pid"


def running(cluster: Cluster) -> int | None:
    """The workers' process id, when they run."""
    try:
        pid = int(_pidfile(cluster).read_text())
        os.kill(pid, 0)
    except (FileNotFoundError, ValueError, ProcessLookupError):
        return None
    return pid


def start(cluster: Cluster, concurrency: int) -> int:
    """Starts the workers unless they run; returns their process id."""
    pid = running(cluster)
    if pid is not None:
        return pid
    dsn = make_conninfo(cluster.dsn(), user=WRITER_ROLE)
    with open(cluster.home / "workers.log", "ab") as log:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "modb.cli",
                "--dsn",
                dsn,
                "worker",
                "--concurrency",
                str(concurrency),
            ],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=log,
            start_new_session=True,  # not stopped by the terminal's Ctrl-C; `modb db stop` stops it
        )
    _pidfile(cluster).write_text(str(process.pid))
    return process.pid


def stop(cluster: Cluster) -> bool:
    """Stops the workers (SIGTERM: each finishes or gives up its job); whether any ran."""
    pid = running(cluster)
    if pid is None:
        _pidfile(cluster).unlink(missing_ok=True)
        return False
    os.killpg(pid, signal.SIGTERM)
    deadline = time.monotonic() + STOP_WAIT_S
    while running(cluster) is not None and time.monotonic() < deadline:
        time.sleep(0.2)
    if running(cluster) is not None:
        os.killpg(pid, signal.SIGKILL)  # their jobs are queued again by the next worker
    _pidfile(cluster).unlink(missing_ok=True)
    return True
