"""Shared fixtures: a throwaway PostgreSQL cluster per test session, fresh databases, the real
data."""

from __future__ import annotations

import itertools
import os
import shutil
import tempfile
from pathlib import Path

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import GRAPH, scratch_database

from modb.database.cluster import Cluster
from modb.database.connection import connect
from modb.demo.data import locomotion_files


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


@pytest.fixture(scope="session")
def locomotion(cluster, tmp_path_factory):
    """Every locomotion clip of ../shared/mocap/bandai-2-dev (419 files), with snippets and the
    transition graph GRAPH (shared by the synthesis and avatar tests, which only read it)."""
    # development: a database this fixture filled before
    if os.environ.get("MODB_TEST_LOCOMOTION_DSN"):
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


@pytest.fixture(scope="session")
def cmu(cluster):
    """CMU 131 (14 ASF/AMC trials, 120 fps) with snippets and their mirror images (shared by the
    selection, roles and mirror tests, which only read it)."""
    with scratch_database(cluster, f"behaviour_{os.getpid()}") as dsn:
        r = run_modb(
            dsn,
            "load",
            *sorted(mocap("cmu", "131").glob("*.amc")),
            "--collection",
            "cmu/131",
            "--mirror",
        )
        assert r.returncode == 0, r.stderr
        yield dsn
