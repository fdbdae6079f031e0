"""How job code connects: a worker as the worker role (its writes to the job tables are the
worker's, what jobs make the loader's, of which it is a member), its connections naming the process
that runs them (modb_jobs.runner: only a job's newest attempt reports); a submitter as itself,
through the job functions. Never a superuser's rights: the login role must be a member."""

from __future__ import annotations

import os
import socket

from psycopg.conninfo import conninfo_to_dict, make_conninfo

LOADER_ROLE = "modb_loader"
WORKER_ROLE = "modb_worker"


def _with_options(conninfo: str, *settings: str) -> str:
    options = conninfo_to_dict(conninfo).get("options") or ""
    added = " ".join(f"-c {setting}" for setting in settings)
    return make_conninfo(conninfo, options=f"{options} {added}".strip())


def as_loader(conninfo: str) -> str:
    """The connection string with the loader role set at connection."""
    return _with_options(conninfo, f"role={LOADER_ROLE}")


def runner() -> str:
    """This process, as the job tables name the worker running an attempt."""
    host = "".join(c for c in socket.gethostname() if c.isalnum() or c in "-.") or "host"
    return f"{host}:{os.getpid()}"


def as_worker(conninfo: str) -> str:
    """The connection string with the worker role set at connection, naming this process."""
    return _with_options(conninfo, f"role={WORKER_ROLE}", f"modb_jobs.runner={runner()}")
