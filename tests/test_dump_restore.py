"""pg_dump / pg_restore keeps the motion and the jobs (the engine's tables and modb's beside them),
and loads after a restore get fresh ids."""

from __future__ import annotations

import subprocess

import numpy as np
import psycopg
from support.commands import run_modb
from support.data import mocap

from modb.clips import read_motion
from modb.database.cluster import _bindir
from modb.database.connection import connect


def test_dump_restore_keeps_clips_and_loading_continues(cluster, fresh_db, db, tmp_path):
    r = run_modb(fresh_db, "load", mocap("cmu", "131", "bvh"), "--units", "0.0564444")
    assert r.returncode == 0, r.stderr
    db.execute('UPDATE modb.clip_versions SET meta = \'{"tags": ["kept"]}\' WHERE clip_id = 1')
    db.execute("INSERT INTO modb.models (name, kind, data) VALUES ('m', 'test', '{\"k\": 1}')")
    db.execute("SELECT modb.build_transition_graph('g', 'locomotion', NULL, 0)")
    db.execute(
        "INSERT INTO modb.match_profiles (name, settings) SELECT 'mine', settings FROM "
        "modb.match_profiles "
        "WHERE name = 'strict'"
    )
    assert run_modb(fresh_db, "worker", "--init").returncode == 0
    queued = run_modb(fresh_db, "graph", "build", "later", "--background")
    waiting = run_modb(fresh_db, "graph", "build", "after", "--background", "--after",
                       queued.stdout.strip())  # fmt: skip
    assert waiting.returncode == 0, waiting.stderr
    jobs = "SELECT id, kind, state, submitter, arguments, waits_for FROM modb.jobs ORDER BY id"
    source_name = psycopg.conninfo.conninfo_to_dict(fresh_db)["dbname"]
    dump = tmp_path / "modb.dump"
    host = str(cluster.socket_dir)
    subprocess.run(
        [_bindir() / "pg_dump", "-h", host, "-U", cluster.os_user, "-Fc", "-f", dump, source_name],
        check=True,
    )
    target = source_name + "_restored"
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{target}"')
    try:
        restore = subprocess.run(
            [
                _bindir() / "pg_restore",
                "-h",
                host,
                "-U",
                cluster.os_user,
                "-d",
                target,
                "--exit-on-error",
                dump,
            ],
            capture_output=True,
            text=True,
        )
        assert restore.returncode == 0, restore.stderr
        with connect(cluster.dsn(target)) as restored:
            query = (
                "SELECT clip_id, name, collection, version, n_frames, meta FROM modb.current_clips "
                "ORDER BY clip_id"
            )
            assert restored.execute(query).fetchall() == db.execute(query).fetchall()
            assert restored.execute("SELECT data FROM modb.models").fetchone()[0] == {"k": 1}
            profiles = "SELECT name, settings, shipped FROM modb.match_profiles ORDER BY name"
            assert restored.execute(profiles).fetchall() == db.execute(profiles).fetchall()
            snippets = (
                "SELECT count(*), sum(first_frame), count(DISTINCT begin_terminator) "
                "FROM modb.snippets"
            )
            assert restored.execute(snippets).fetchone() == db.execute(snippets).fetchone()
            graph = (
                "SELECT g.name, g.data, array_agg(s.snippet_id ORDER BY s.snippet_id) FROM "
                "modb.graphs g "
                "JOIN modb.graph_snippets s ON s.graph_id = g.id GROUP BY g.name, g.data"
            )
            assert restored.execute(graph).fetchall() == db.execute(graph).fetchall() != []
            assert db.execute(snippets).fetchone()[0] > 0
            assert (
                restored.execute(
                    "SELECT count(*) FROM modb.select_next_snippet(1, '{0,1}', 'mine')"
                ).fetchone()[0]
                == 1
            )
            for (clip_id,) in db.execute("SELECT id FROM modb.clips").fetchall():
                a, b = read_motion(db, clip_id), read_motion(restored, clip_id)
                assert np.array_equal(a.rotations, b.rotations) and np.array_equal(
                    a.translations, b.translations
                )
            max_before = restored.execute("SELECT max(id) FROM modb.clips").fetchone()[0]
            assert restored.execute(jobs).fetchall() == db.execute(jobs).fetchall()
            assert [r[2] for r in db.execute(jobs)] == ["queued", "waiting"]
        # the restored jobs still work: cancelling the first cancels the one waiting for it
        r = run_modb(cluster.dsn(target), "jobs", "cancel", queued.stdout.strip())
        assert r.returncode == 0, r.stderr
        with connect(cluster.dsn(target)) as restored:
            assert [r[2] for r in restored.execute(jobs)] == ["cancelled", "cancelled"]
        r = run_modb(
            cluster.dsn(target), "load", mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
        )
        assert r.returncode == 0, r.stderr
        with connect(cluster.dsn(target)) as restored:
            new_ids = restored.execute(
                "SELECT id FROM modb.clips WHERE id > %s", [max_before]
            ).fetchall()
            assert len(new_ids) == 1
            (collections,) = restored.execute("SELECT count(*) FROM modb.collections").fetchone()
            assert collections == 2
    finally:
        with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{target}" WITH (FORCE)')
