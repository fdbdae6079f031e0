"""Least privilege as a user meets it: a login in modb_loader loads; a login in modb_reader only reads."""
from __future__ import annotations

import psycopg

from conftest import mocap, run_modb


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
