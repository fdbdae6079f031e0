"""The embedded database's job workers (`modb db start --workers N`, stopped by `modb db stop`): one
`modb worker --concurrency N` in its own session, logging to home/workers.log, connected as the web
role (a member of modb_loader, not a superuser)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time

from pathlib import Path

from psycopg.conninfo import make_conninfo

from .cluster import WRITER_ROLE, Cluster

STOP_WAIT_S = 60  # a running job finishes its current step first


def _pidfile(cluster: Cluster):
    return cluster.home / "workers.pid"


def running(cluster: Cluster) -> int | None:
    """The workers' process id, when they run."""
    try:
        pid = int(_pidfile(cluster).read_text())
        command = (Path("/proc") / str(pid) / "cmdline").read_bytes()
    except (OSError, ValueError):
        return None
    # after a reboot the number may be another process's
    return pid if b"modb.cli" in command and b"worker" in command else None


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
    """Stops the workers (SIGTERM: each finishes its job; after STOP_WAIT_S they are killed and
    their jobs run again on the next worker); whether any ran."""
    pid = running(cluster)
    if pid is None:
        _pidfile(cluster).unlink(missing_ok=True)
        return False
    os.kill(pid, signal.SIGTERM)  # the parent stops its processes
    deadline = time.monotonic() + STOP_WAIT_S
    while running(cluster) is not None and time.monotonic() < deadline:
        time.sleep(0.2)
    if running(cluster) is not None:
        children = _children(pid)  # each in a process group of its own
        os.killpg(pid, signal.SIGKILL)
        for child in children:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(child, signal.SIGKILL)
    _pidfile(cluster).unlink(missing_ok=True)
    return True


def _children(pid: int) -> list[int]:
    """The worker processes a `modb worker --concurrency N` started (each its own process group)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            if int(stat.read_text().rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(stat.parent.name))
        except (OSError, IndexError, ValueError):
            continue
    return found
