"""Least privilege as a user meets it: a login in modb_loader loads; a login in modb_reader only
reads."""

from __future__ import annotations

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap

from modb.database.connection import connect


def test_loader_and_reader_logins(cluster, fresh_db, db, tmp_path):
    db.execute("DROP ROLE IF EXISTS test_ingest")
    db.execute("DROP ROLE IF EXISTS test_animator")
    db.execute("CREATE ROLE test_ingest LOGIN IN ROLE modb_loader")
    db.execute("CREATE ROLE test_animator LOGIN IN ROLE modb_reader")
    try:
        as_loader = psycopg.conninfo.make_conninfo(fresh_db, user="test_ingest")
        as_reader = psycopg.conninfo.make_conninfo(fresh_db, user="test_animator")
        walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
        r = run_modb(as_reader, "load", walk)
        assert r.returncode == 1 and "permission denied" in r.stderr
        r = run_modb(as_loader, "load", walk)
        assert r.returncode == 0, r.stderr
        r = run_modb(as_reader, "export", "dataset-1_walk_active_001", "--out", tmp_path / "w.bvh")
        assert r.returncode == 0, r.stderr
        with psycopg.connect(as_loader) as conn:
            (created_by,) = conn.execute("SELECT created_by FROM modb.clip_versions").fetchone()
            assert created_by == "test_ingest"
    finally:
        db.execute("DROP OWNED BY test_ingest, test_animator")
        db.execute("DROP ROLE test_ingest")
        db.execute("DROP ROLE test_animator")


def test_reader_selects_loader_builds(cmu):
    with connect(cmu) as conn:
        conn.execute("DROP ROLE IF EXISTS t_reader")
        conn.execute("CREATE ROLE t_reader LOGIN IN ROLE modb_reader")
    try:
        with psycopg.connect(psycopg.conninfo.make_conninfo(cmu, user="t_reader")) as conn:
            assert (
                conn.execute(
                    "SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,1}')"
                ).fetchone()[0]
                == 1
            )
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute("SELECT modb.build_snippets()")
    finally:
        with connect(cmu) as conn:
            conn.execute("DROP ROLE t_reader")
