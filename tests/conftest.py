"""Shared fixtures: a throwaway PostgreSQL cluster per test session, fresh databases, the real data."""
from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import psycopg
import pytest

from modb.database.cluster import Cluster
from modb.database.connection import connect
from modb.demo.data import locomotion_files

REPO = Path(__file__).resolve().parents[1]
MOCAP = Path(os.environ.get("MODB_MOCAP", REPO.parent / "shared" / "mocap"))
CMU_UNITS = 0.0254 / 0.45  # metres per CMU ASF length unit (:units length 0.45)


def mocap(*parts: str) -> Path:
    """A path in the shared real data; the test is skipped, saying why, when it is absent."""
    p = MOCAP.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"real motion data not found at {p} (set MODB_MOCAP to the mocap folder)")
    return p


@pytest.fixture(scope="session")
def cluster():
    """A private cluster in a temporary MODB_HOME, stopped and removed at the end."""
    home = Path(tempfile.mkdtemp(prefix="modb-test-"))
    c = Cluster(home)
    c.init()
    c.start()
    yield c
    c.stop()
    shutil.rmtree(home, ignore_errors=True)


_counter = itertools.count()


@pytest.fixture
def fresh_db(cluster, request) -> str:
    """Conninfo of a new database with the extension installed (dropped after the test)."""
    name = f"t{os.getpid()}_{next(_counter)}"
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb CASCADE")
    yield cluster.dsn(name)
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as conn:
        conn.execute(f'DROP DATABASE "{name}" WITH (FORCE)')


@pytest.fixture
def db(fresh_db):
    with connect(fresh_db) as conn:
        yield conn


@contextlib.contextmanager
def scratch_database(cluster, name: str):
    """A database with the extension for a whole test module (dropped at the end)."""
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}"')
        admin.execute(f'CREATE DATABASE "{name}"')
    with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb CASCADE")
    try:
        yield cluster.dsn(name)
    finally:
        with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
            admin.execute(f'DROP DATABASE "{name}" WITH (FORCE)')


def run_modb(dsn: str, *args: str) -> subprocess.CompletedProcess:
    """The real command line, as a user runs it."""
    return subprocess.run([sys.executable, "-m", "modb.cli", "--dsn", dsn, *map(str, args)],
                          capture_output=True, text=True)


def plan_nodes(conn: psycopg.Connection, sql: str, params=()) -> list[dict]:
    """Every node of the plan EXPLAIN (ANALYZE, FORMAT JSON) shows for a query, depth first."""
    nodes, todo = [], [conn.execute("EXPLAIN (ANALYZE, FORMAT JSON) " + sql, params).fetchone()[0][0]["Plan"]]
    while todo:
        node = todo.pop()
        nodes.append(node)
        todo.extend(reversed(node.get("Plans", [])))
    return nodes


GRAPH = "locomotion"  # the locomotion fixture's transition graph


@pytest.fixture(scope="session")
def locomotion(cluster, tmp_path_factory):
    """Every locomotion clip of ../shared/mocap/bandai-2-dev (419 files), with snippets and the transition
    graph GRAPH (shared by the synthesis and avatar tests, which only read it)."""
    if os.environ.get("MODB_TEST_LOCOMOTION_DSN"):  # development: a database this fixture filled before
        yield os.environ["MODB_TEST_LOCOMOTION_DSN"]
        return
    data = mocap("bandai-2-dev", "data")
    folder = tmp_path_factory.mktemp("locomotion")
    for f in locomotion_files(data):
        os.symlink(f, folder / f.name)
    with scratch_database(cluster, f"synthesis_{os.getpid()}") as dsn:
        r = run_modb(dsn, "load", folder, "--collection", "bandai-2/locomotion", "-q")
        assert r.returncode == 0, r.stderr
        r = run_modb(dsn, "graph", "build", GRAPH, "-q")
        assert r.returncode == 0, r.stderr
        yield dsn
