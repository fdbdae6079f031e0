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


def _login(db, fresh_db, name: str, role: str) -> str:
    db.execute(f"DROP ROLE IF EXISTS {name}")
    db.execute(f"CREATE ROLE {name} LOGIN IN ROLE {role}")
    return psycopg.conninfo.make_conninfo(fresh_db, user=name)


def test_every_loader_command_works_as_a_loader_login(cluster, fresh_db, db, tmp_path):
    """`modb load` (new, mirrored, unchanged, a changed file's new version) and `modb graph build`
    (and rebuild) as a non-superuser login in modb_loader: exit 0, no warning, snippets built."""
    as_loader = _login(db, fresh_db, "test_loader_cli", "modb_loader")
    try:
        walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
        other = mocap("bandai-1", "data", "dataset-1_walk_normal_001.bvh")
        for args in (
            [walk],
            [other, "--mirror"],
            [walk],  # unchanged
        ):
            r = run_modb(as_loader, "load", *args, "--collection", "walks")
            assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
        changed = tmp_path / walk.name
        lines = walk.read_text().splitlines()
        lines[-1] = " ".join(f"{float(x) + 0.5:g}" for x in lines[-1].split())
        changed.write_text("\n".join(lines) + "\n")
        r = run_modb(as_loader, "load", changed, "--collection", "walks")
        assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
        versions = db.execute(
            "SELECT v.version, count(s.id), count(s.future_translation) FROM modb.clip_versions v "
            "JOIN modb.clips c ON c.id = v.clip_id LEFT JOIN modb.snippets s "
            "ON s.clip_id = v.clip_id AND s.version = v.version "
            "WHERE c.name = %s GROUP BY 1 ORDER BY 1",
            [walk.stem],
        ).fetchall()
        # the new version's snippets replaced the old one's (deleted through snippet_sources)
        assert [v[0] for v in versions] == [1, 2] and versions[0][1] == 0
        assert versions[1][1] > 0 and versions[1][2] == versions[1][1]
        assert db.execute("SELECT count(*) FROM modb.snippets WHERE mirrored").fetchone()[0] > 0
        for _ in range(2):  # built, then rebuilt over the first
            r = run_modb(as_loader, "graph", "build", "walks", "--min-turn", "0", "-q")
            assert r.returncode == 0, r.stderr
        assert db.execute("SELECT count(*) FROM modb.graphs").fetchone()[0] == 1
        # a graph is deleted through its name, with its rows
        with psycopg.connect(as_loader) as conn:
            with pytest.raises(psycopg.errors.InsufficientPrivilege), conn.transaction():
                conn.execute("DELETE FROM modb.graphs")
            conn.execute("DELETE FROM modb.graph_names WHERE name = 'walks'")
            conn.commit()
        assert db.execute(
            "SELECT (SELECT count(*) FROM modb.graphs), (SELECT count(*) FROM modb.graph_snippets)"
        ).fetchone() == (0, 0)
        (created_by,) = db.execute("SELECT DISTINCT created_by FROM modb.clip_versions").fetchone()
        assert created_by == "test_loader_cli"
        # the catalogue edits, as the loader: version 1 current again (3), then gone again; a
        # segment cut; the collection renamed; a clip deleted
        for args in (
            ["clip", "restore", f"walks/{walk.stem}", "--version", "1"],
            ["clip", "delete", f"walks/{walk.stem}", "--version", "3"],
            ["annotate", f"walks/{walk.stem}", "--segment", "step:0-40"],
            ["split", f"walks/{walk.stem}", "--by-annotation"],
            ["collection", "rename", "walks", "strolls"],
            ["clip", "delete", f"strolls/{other.stem}"],
        ):
            r = run_modb(as_loader, *args)
            assert r.returncode == 0 and "warning" not in r.stderr, (args, r.stderr)
        kept = db.execute(
            "SELECT c.name, modb.collection_path(c.collection_id), array_agg(DISTINCT v.version), "
            "array_agg(DISTINCT s.version) FROM modb.clips c JOIN modb.clip_versions v "
            "ON v.clip_id = c.id LEFT JOIN modb.snippets s ON s.clip_id = c.id GROUP BY 1, 2"
        ).fetchall()
        assert kept == [(walk.stem, "strolls", [1, 2], [2])]
        assert db.execute("SELECT count(*) FROM modb.clip_segments").fetchone()[0] == 1
    finally:
        db.execute("DROP OWNED BY test_loader_cli")
        db.execute("DROP ROLE test_loader_cli")


# Every table a selection reads (select_next_snippet's plan opens them all, graph or not).
READER_TABLES = (
    "snippets",
    "terminators",
    "clip_versions",
    "clips",
    "skeletons",
    "collections",
    "match_profiles",
    "graphs",
    "graph_snippets",
    "graph_transitions",
)


def test_loader_gets_only_what_loading_needs(cluster, fresh_db, db):
    r = run_modb(fresh_db, "load", mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh"))
    assert r.returncode == 0, r.stderr
    as_loader = _login(db, fresh_db, "test_loader_limits", "modb_loader")
    try:
        with psycopg.connect(as_loader) as conn:
            # no exclusive lock on what the selection reads
            for table in READER_TABLES:
                with pytest.raises(psycopg.errors.InsufficientPrivilege), conn.transaction():
                    conn.execute(f"LOCK modb.{table} IN ACCESS EXCLUSIVE MODE")
            # who and when are the server's
            for column, value in (("created_by", "someone_else"), ("created_at", "2001-01-01")):
                with pytest.raises(psycopg.errors.InsufficientPrivilege), conn.transaction():
                    conn.execute(
                        f"INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, "
                        f"rotations, {column}) SELECT clip_id, skeleton_id, fps, n_frames, "
                        f"rotations, %s FROM modb.clip_versions LIMIT 1",
                        [value],
                    )
            # the shipped profiles are the extension's; a profile of one's own is editable
            with pytest.raises(psycopg.errors.InsufficientPrivilege) as refused:
                with conn.transaction():
                    conn.execute(
                        "UPDATE modb.match_profiles SET settings = '{}' WHERE name = 'default'"
                    )
            assert "shipped" in str(refused.value)
            for statement in (
                "DELETE FROM modb.match_profiles WHERE name = 'default'",
                "INSERT INTO modb.match_profiles (name, settings, shipped) "
                "VALUES ('x', '{}', true)",
                "DELETE FROM modb.snippets",
                "UPDATE modb.snippets SET net_heading = 0",
                "DELETE FROM modb.clip_versions",  # modb.delete_clip_version deletes one
                "DELETE FROM modb.clips",
                "DELETE FROM modb.collections",
            ):
                with pytest.raises(psycopg.errors.InsufficientPrivilege), conn.transaction():
                    conn.execute(statement)
            conn.execute(
                "INSERT INTO modb.match_profiles (name, settings) "
                "SELECT 'mine', settings FROM modb.match_profiles WHERE name = 'default'"
            )
            conn.execute(
                'UPDATE modb.match_profiles SET settings = settings || \'{"position_threshold": '
                "0.5}' WHERE name = 'mine'"
            )
            conn.commit()
        assert db.execute(
            "SELECT settings->>'position_threshold' FROM modb.match_profiles WHERE name = 'mine'"
        ).fetchone() == ("0.5",)
        as_reader = _login(db, fresh_db, "test_reader_limits", "modb_reader")
        with psycopg.connect(as_reader) as conn:
            for statement in (
                "SELECT modb.delete_clip(1)",
                "SELECT modb.delete_collection('x')",
                "SELECT modb.restore_clip_version(1, 1)",
                "SELECT modb.rename_collection('x', 'y')",
            ):
                with pytest.raises(psycopg.errors.InsufficientPrivilege), conn.transaction():
                    conn.execute(statement)
    finally:
        for role in ("test_loader_limits", "test_reader_limits"):
            db.execute(f"DROP OWNED BY {role}")
            db.execute(f"DROP ROLE IF EXISTS {role}")
