"""What the workers of one test run share (pytest-xdist runs several, each its own process): one
private cluster, a template database with the extension that fresh databases are copied from, and
databases built once and only read after (the locomotion graph, CMU 131).

The process that starts pytest makes a run folder and names it in MODB_TEST_RUN; its workers
inherit it. Whichever worker first needs a resource builds it under a file lock there; the others
wait for it and use it. The starting process stops the cluster at the end of the run.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import psycopg
import pytest
from filelock import FileLock

from modb.database.cluster import Cluster

RUN = "MODB_TEST_RUN"
TEMPLATE = "modb_template"  # a database with the extension and nothing else
# A throwaway cluster need not survive a power cut: no fsync (dropping a database checkpoints).
NOT_DURABLE = "fsync = off\nsynchronous_commit = off\nfull_page_writes = off\n"


def start_run() -> Path | None:
    """The run folder of a new run, or None when this process is a worker of a run already."""
    if os.environ.get(RUN):
        return None
    folder = Path(tempfile.mkdtemp(prefix="modb-test-"))
    folder.chmod(0o711)  # the cluster's OS user (postgres, when run as root) passes through it
    os.environ[RUN] = str(folder)
    return folder


def end_run(folder: Path) -> None:
    cluster = Cluster(folder / "cluster")
    if cluster.is_initialized():
        cluster.stop()
    shutil.rmtree(folder, ignore_errors=True)


def _folder() -> Path:
    return Path(os.environ[RUN])


def cluster() -> Cluster:
    """The run's cluster, started by the first worker that asks, with the template database."""
    c = Cluster(_folder() / "cluster")
    with FileLock(_folder() / "cluster.lock"):
        if not (_folder() / "cluster.ready").exists():
            c.init()
            with open(c.datadir / "postgresql.auto.conf", "a") as conf:
                conf.write(NOT_DURABLE)
            c.start()  # also makes the roles the extension and `modb serve` use, once
            with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
                admin.execute(f'CREATE DATABASE "{TEMPLATE}"')
            with psycopg.connect(c.dsn(TEMPLATE), autocommit=True) as conn:
                conn.execute("CREATE EXTENSION modb CASCADE")
            (_folder() / "cluster.ready").touch()
    return c


def create_database(c: Cluster, name: str) -> str:
    """A new database with the extension (a copy of the template: what CREATE EXTENSION makes)."""
    with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{name}" TEMPLATE "{TEMPLATE}"')
    return c.dsn(name)


def drop_database(c: Cluster, name: str) -> None:
    with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


def built_once(c: Cluster, name: str, build: Callable[[str], None]) -> str:
    """Database `name`, built by build(dsn) in the first worker that asks and shared by all (they
    only read it). A failed build fails every test that needs it, with its message, once."""
    failed = _folder() / f"{name}.failed"
    with FileLock(_folder() / f"{name}.lock"):
        if failed.exists():
            pytest.fail(f"building the shared database {name} failed:\n{failed.read_text()}")
        if not (_folder() / f"{name}.ready").exists():
            dsn = create_database(c, name)
            try:
                build(dsn)
            except pytest.skip.Exception:
                drop_database(c, name)
                raise
            except BaseException as e:
                failed.write_text(f"{type(e).__name__}: {e}")
                drop_database(c, name)
                raise
            (_folder() / f"{name}.ready").touch()
    return c.dsn(name)
