"""What the workers of one test run share (pytest-xdist runs several, each its own process): one
private cluster, a template database with the extension that fresh databases are copied from,
databases built once and only read after (the locomotion graph, CMU 131), and databases built once
as templates that each module needing one copies to write in (CMU 16's step models).

The process that starts pytest makes a run folder and names it in MODB_TEST_RUN; its workers
inherit it. Whichever worker first needs a resource builds it under a file lock there; the others
wait for it and use it. The starting process stops the cluster at the end of the run.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import psycopg
import pytest
from filelock import FileLock

from modb.database.cluster import Cluster

RUN = "MODB_TEST_RUN"
TEMPLATE = "modb_template"  # a database with the extension and nothing else
# A throwaway cluster need not survive a power cut: no fsync (dropping a database checkpoints).
NOT_DURABLE = "fsync = off\nsynchronous_commit = off\nfull_page_writes = off\n"

# Clusters thrown away after the module: in memory where there is room (/dev/shm), else in the
# temporary folder. Their checkpoints and base backups sync every file they write; on a disk other
# processes share that was most of this module's time.
IN_MEMORY = Path("/dev/shm")
IN_MEMORY_FREE = 4 * 2**30  # bytes: three nodes' data and WAL, several times over


def throwaway_folder(prefix: str) -> Path:
    """A new folder for clusters, in memory if there is room, which the clusters' OS user may pass
    through (the `postgres` user, when run as root)."""
    room = IN_MEMORY.is_dir() and shutil.disk_usage(IN_MEMORY).free > IN_MEMORY_FREE
    folder = Path(tempfile.mkdtemp(prefix=prefix, dir=IN_MEMORY if room else None))
    folder.chmod(0o711)
    return folder


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


def keep(name: str, data) -> None:
    """Keeps `data` (JSON) in the run's folder as `name`, for every worker: what a shared build
    printed, say, that a module checks (kept(name))."""
    (_folder() / f"{name}.json").write_text(json.dumps(data))


def kept(name: str):
    """What keep(name, data) kept in this run."""
    return json.loads((_folder() / f"{name}.json").read_text())


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


def create_database(c: Cluster, name: str, template: str = TEMPLATE) -> str:
    """A new database, a copy of `template` (by default the run's template with the extension: what
    CREATE EXTENSION makes)."""
    with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{name}" TEMPLATE "{template}"')
    return c.dsn(name)


def drop_database(c: Cluster, name: str) -> None:
    with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


def built_once(c: Cluster, name: str, build: Callable[[str], None]) -> str:
    """Database `name`, built by build(dsn) in the first worker that asks and shared by all (they
    only read it). A failed build fails every test that needs it, with its message, once."""
    with FileLock(_folder() / f"{name}.lock"):
        _build_once(c, name, build)
    return c.dsn(name)


@contextlib.contextmanager
def copy_of_built(
    c: Cluster, built_name: str, build: Callable[[str], None], copy_name: str
) -> Iterator[str]:
    """A copy of database `built_name` for the caller alone, to read and write (CREATE DATABASE
    copy_name TEMPLATE built_name), dropped after. `built_name` is built by build(dsn) once per run,
    in the first worker that asks, and then kept as a template nobody connects to (ALLOW_CONNECTIONS
    false: CREATE DATABASE ... TEMPLATE refuses while anyone is connected to it). A failed build
    fails every copy, with its message, once. The copies are made under the build's lock, one at a
    time: two workers copying at once cannot see each other as users of the template."""
    with FileLock(_folder() / f"{built_name}.lock"):
        _build_once(c, built_name, build, template=True)
        with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
            _disconnect(admin, built_name)  # nobody should be: a backend left over, say
        dsn = create_database(c, copy_name, template=built_name)
    try:
        yield dsn
    finally:
        drop_database(c, copy_name)


def _build_once(
    c: Cluster, name: str, build: Callable[[str], None], template: bool = False
) -> None:
    """Builds database `name` unless this run has (the caller holds its lock); a template (to copy,
    never to use) takes no connections after."""
    failed = _folder() / f"{name}.failed"
    if failed.exists():
        pytest.fail(f"building the shared database {name} failed:\n{failed.read_text()}")
    if (_folder() / f"{name}.ready").exists():
        return
    dsn = create_database(c, name)
    try:
        build(dsn)
        if template:
            with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
                admin.execute(
                    f'ALTER DATABASE "{name}" WITH IS_TEMPLATE true ALLOW_CONNECTIONS false'
                )
                _disconnect(admin, name)  # the builder's own, if it kept any
    except pytest.skip.Exception:
        _drop_built(c, name)
        raise
    except BaseException as e:
        failed.write_text(f"{type(e).__name__}: {e}")
        _drop_built(c, name)
        raise
    (_folder() / f"{name}.ready").touch()


def _disconnect(admin: psycopg.Connection, name: str) -> None:
    """Ends every session on database `name`, waiting up to 5 s for each to end."""
    admin.execute(
        "SELECT pg_terminate_backend(pid, 5000) FROM pg_stat_activity "
        "WHERE datname = %s AND pid <> pg_backend_pid()",
        [name],
    )


def _drop_built(c: Cluster, name: str) -> None:
    """Drops what a failed or skipped build left (a template is not dropped: unmark it first)."""
    with psycopg.connect(c.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'ALTER DATABASE "{name}" WITH IS_TEMPLATE false')
    drop_database(c, name)
