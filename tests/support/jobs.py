"""Watching jobs in tests: a job's row (modb.jobs), its engine events, workers started and stopped
as separate processes (as other machines would run them), and waiting for a job's state."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import psycopg

STALLED_AFTER = "4"  # seconds: a killed worker's job is queued again soon after


def job(conn: psycopg.Connection, job_id: int) -> dict:
    return conn.execute("SELECT to_jsonb(j) FROM modb.jobs j WHERE id = %s", [job_id]).fetchone()[0]


def events(conn: psycopg.Connection, job_id: int, kind: str) -> int:
    return conn.execute(
        "SELECT count(*) FROM procrastinate_events WHERE job_id = %s AND type = %s", [job_id, kind]
    ).fetchone()[0]


def worker(dsn: str, *args: str) -> subprocess.Popen:
    """`modb worker ARGS...`, a process of its own (its housekeeping every STALLED_AFTER / 3 s)."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "modb.cli",
            "--dsn",
            dsn,
            "worker",
            "--stalled-after",
            STALLED_AFTER,
            *args,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def stop(*workers: subprocess.Popen) -> None:
    for w in workers:
        if w.poll() is None:
            w.send_signal(signal.SIGTERM)
    for w in workers:
        w.wait(timeout=60)


def until(conn: psycopg.Connection, job_id: int, ready, seconds: float, what: str) -> dict:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        state = job(conn, job_id)
        if ready(state):
            return state
        time.sleep(0.05)
    raise AssertionError(f"job {job_id}: not {what} within {seconds} s: {job(conn, job_id)}")
