"""Jobs over clips (issue 42) on real capture: CMU 131 trials retargeted onto a Bandai rig and
edited by a script, computed in the worker's (or the command's) process with the kernel, checked
against what the server's own modb.retarget and modb.apply_edit_script store (the same kernel code
through PL/Python: this checks the worker's reads and writes; test_upgrade checks that code against
0.19.0's, the last written for the server alone); a job waiting for
others; a cancel leaving whole clips, listed; a worker killed mid-job leaving no clip edited twice;
a collection's retargeting through REST."""

from __future__ import annotations

import os

import numpy as np
import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database
from support.jobs import job, stop, until, worker

from modb.database.connection import connect

# Four trials: a job over all of them still runs when it is stopped after its first one or two.
TRIALS = [f"131_0{i}" for i in range(1, 5)]
# What a clip's current version stores, ids left out: its frames, then its terminators and
# snippets as numbers (numpy's sums may differ in the last bit from run to run).
STORED = """
SELECT v.n_frames, v.fps, v.skeleton_id, (SELECT array_agg(x) FROM unnest(v.rotations) x),
       (SELECT array_agg(ARRAY[t.frame, t.mirrored::int, t.heading, t.pelvis_height]
                         || t.positions || t.rotations || t.velocities ORDER BY t.mirrored, t.frame)
          FROM modb.terminators t WHERE t.clip_id = v.clip_id AND t.version = v.version),
       (SELECT array_agg(ARRAY[s.first_frame, s.mirrored::int, s.net_heading, s.future_heading]
                         || s.net_translation || s.future_translation
                         ORDER BY s.mirrored, s.first_frame)
          FROM modb.snippets s WHERE s.clip_id = v.clip_id AND s.version = v.version)
  FROM modb.current_clips c JOIN modb.clip_versions v USING (clip_id, version)
 WHERE c.clip_id = %s
"""
SCRIPTS = {
    "t": '[{"op": "mirror"}, {"op": "smooth", "seconds": 0.1}, '
    '{"op": "trim", "start": 5, "end": 240}]',
    "again": '[{"op": "mirror"}, {"op": "smooth", "seconds": 0.2}]',  # any length, any time
    "too long": '[{"op": "trim", "start": 0, "end": 99999}]',  # fails on these clips
}


@pytest.fixture(scope="module")
def dsn(cluster):
    with scratch_database(cluster, f"clip_jobs_{os.getpid()}") as dsn:
        trials = [mocap("cmu", "131", f"{t}.amc") for t in TRIALS]
        walk = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[0]
        for files, collection in ((trials, "cmu"), ([walk], "bandai")):
            r = run_modb(dsn, "load", *files, "--collection", collection, "-q", process=False)
            assert r.returncode == 0, r.stderr
        r = run_modb(dsn, "worker", "--init", process=False)
        assert r.returncode == 0, r.stderr
        with connect(dsn) as conn:
            for name, commands in SCRIPTS.items():
                conn.execute(
                    "INSERT INTO modb.edit_scripts (name, commands) VALUES (%s, %s)",
                    [name, commands],
                )
        yield dsn


def clip_ids(conn: psycopg.Connection, collection: str) -> list[int]:
    return [
        r[0]
        for r in conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = %s ORDER BY name",
            [collection],
        )
    ]


def bandai_skeleton(conn: psycopg.Connection) -> int:
    return conn.execute(
        "SELECT skeleton_id FROM modb.current_clips WHERE collection = 'bandai'"
    ).fetchone()[0]


def same_numbers(made, oracle) -> bool:
    assert made[:3] == oracle[:3]
    return all(
        np.allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=1e-9, atol=1e-12)
        for a, b in zip(made[3:], oracle[3:], strict=True)
    )


def test_clip_jobs_store_what_the_server_stores(dsn):
    with connect(dsn) as conn:
        clip = clip_ids(conn, "cmu")[0]
        skeleton = bandai_skeleton(conn)
        # the oracles: the server's own functions, in transactions rolled back
        with conn.transaction(force_rollback=True):
            made = conn.execute(
                "SELECT modb.retarget(%s, %s, 'oracle', NULL, true)", [clip, skeleton]
            ).fetchone()[0]
            retargeted = conn.execute(STORED, [made]).fetchone()
        with conn.transaction(force_rollback=True):
            conn.execute("SELECT * FROM modb.apply_edit_script('t', ARRAY[%s]::bigint[])", [clip])
            edited = conn.execute(STORED, [clip]).fetchone()
    r = run_modb(dsn, "retarget", f"id:{clip}", "--to", str(skeleton), "--collection", "rt",
                 "--mirror", process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "no worker is running" in r.stderr and "running it in this process" in r.stderr
    assert f"clip {clip} -> rt/" in r.stdout and "1 clips retargeted onto skeleton" in r.stdout
    r = run_modb(dsn, "edit", "apply", "t", f"id:{clip}", process=False)
    assert r.returncode == 0 and f"clip {clip}: version 2 (236 frames" in r.stdout, r.stderr
    with connect(dsn) as conn:
        (made,) = clip_ids(conn, "rt")
        assert same_numbers(conn.execute(STORED, [made]).fetchone(), retargeted)
        # --mirror: the clip's snippets and their mirror images (0.19.0 cut the images only)
        assert conn.execute(
            "SELECT array_agg(DISTINCT mirrored ORDER BY mirrored) FROM modb.snippets "
            "WHERE clip_id = %s",
            [made],
        ).fetchone()[0] == [False, True]
        assert same_numbers(conn.execute(STORED, [clip]).fetchone(), edited)
        kinds = conn.execute(
            "SELECT kind, state, result->'clips'->0->>'clip_id' FROM modb.jobs ORDER BY id"
        ).fetchall()
        assert kinds == [
            ("modb.retarget", "done", str(made)),
            ("modb.apply_edit_script", "done", str(clip)),
        ]


def test_a_job_waits_for_the_jobs_it_needs_and_not_for_a_failed_one(dsn):
    with connect(dsn) as conn:
        clips = clip_ids(conn, "cmu")[1:3]
        skeleton = bandai_skeleton(conn)
    ids = [f"id:{c}" for c in clips]
    r = run_modb(dsn, "retarget", *ids, "--to", str(skeleton), "--collection", "needed",
                 "--background", process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    retargeting = int(r.stdout)
    r = run_modb(dsn, "graph", "build", "after", "--collection", "needed", "--min-turn", "0",
                 "--background", "--after", str(retargeting), process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    graph = int(r.stdout)
    # a script that cannot run on these clips: its job fails, and its waiter is cancelled
    r = run_modb(dsn, "edit", "apply", "too long", ids[0], "--background", process=False)
    failing = int(r.stdout)
    r = run_modb(dsn, "split", ids[0], "--by-annotation", "--background", "--after", str(failing),
                 process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    orphan = int(r.stdout)
    with connect(dsn) as conn:
        assert job(conn, graph)["state"] == "waiting" and job(conn, graph)["waits_for"] == [
            retargeting
        ]
        w = worker(dsn)
        try:
            until(conn, graph, lambda j: j["state"] == "done", 300, "done")
            until(conn, orphan, lambda j: j["state"] == "cancelled", 120, "cancelled")
        finally:
            stop(w)
        first, then = job(conn, retargeting), job(conn, graph)
        assert first["finished_at"] <= then["started_at"]
        assert job(conn, failing)["state"] == "failed"
        assert "frame" in job(conn, failing)["error"]
        assert job(conn, orphan)["error"] == (
            f"job {failing}, which this one waited for, failed: nothing was run"
        )
        # the graph is made of the snippets the retargeting made
        assert (
            conn.execute(
                "SELECT count(*) FROM modb.graph_transitions t "
                "JOIN modb.graphs g ON g.id = t.graph_id "
                "JOIN modb.snippets s ON s.id = t.from_snippet WHERE g.name = 'after' "
                "AND s.clip_id = ANY (%s)",
                [clip_ids(conn, "needed")],
            ).fetchone()[0]
            > 0
        )
    r = run_modb(dsn, "graph", "build", "never", "--background", "--after", str(failing))
    assert r.returncode == 2 and f"job {failing} failed" in r.stderr, r.stderr


def test_a_cancelled_clip_job_keeps_the_clips_it_finished_whole_and_listed(dsn):
    with connect(dsn) as conn:
        clips = clip_ids(conn, "cmu")
        skeleton = bandai_skeleton(conn)
    r = run_modb(dsn, "retarget", *[f"id:{c}" for c in clips], "--to", str(skeleton), "--fps",
                 "120",
                 "--mirror", "--collection", "stopped", "--background", process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    job_id = int(r.stdout)
    w = worker(dsn)
    try:
        with connect(dsn) as conn:
            until(conn, job_id, lambda j: (j["done"] or 0) >= 1, 300, "one clip in")
            assert run_modb(dsn, "jobs", "cancel", str(job_id), process=False).returncode == 0
            state = until(conn, job_id, lambda j: j["state"] != "running", 120, "stopped")
            assert state["state"] == "cancelled"
            listed = [c["clip_id"] for c in state["result"]["clips"]]
            assert 1 <= len(listed) < len(clips)
            assert sorted(clip_ids(conn, "stopped")) == sorted(listed)
            # each finished clip whole: its version cut into snippets and their mirror images
            for made in listed:
                assert conn.execute(
                    "SELECT count(*) FILTER (WHERE mirrored) > 0 "
                    "AND count(*) FILTER (WHERE NOT mirrored) > 0 "
                    "FROM modb.snippets WHERE clip_id = %s",
                    [made],
                ).fetchone()[0]
    finally:
        stop(w)


def test_a_worker_killed_mid_edit_leaves_no_clip_edited_twice(dsn):
    with connect(dsn) as conn:
        clips = clip_ids(conn, "cmu")
        versions = dict(
            conn.execute(
                "SELECT clip_id, version FROM modb.current_clips WHERE clip_id = ANY (%s)", [clips]
            ).fetchall()
        )
    r = run_modb(dsn, "edit", "apply", "again", *[f"id:{c}" for c in clips], "--background",
                 process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    job_id = int(r.stdout)
    first = worker(dsn)
    try:
        with connect(dsn) as conn:
            until(conn, job_id, lambda j: (j["done"] or 0) >= 2, 300, "two clips in")
            first.kill()
            first.wait(timeout=30)
            second = worker(dsn)
            try:
                state = until(conn, job_id, lambda j: j["state"] == "done", 300, "done")
            finally:
                stop(second)
            assert state["attempts"] == 2
            after = dict(
                conn.execute(
                    "SELECT clip_id, version FROM modb.current_clips WHERE clip_id = ANY (%s)",
                    [clips],
                ).fetchall()
            )
            assert after == {c: v + 1 for c, v in versions.items()}  # one new version each
            made_by = conn.execute(
                "SELECT count(*) FROM modb.clip_versions "
                "WHERE (load_params->'edit_script'->>'job')::bigint = %s",
                [job_id],
            ).fetchone()[0]
            assert made_by == len(clips)
    finally:
        stop(first)


def test_rest_retargets_a_whole_collection_as_a_job(dsn):
    import httpx
    from support.browser import serving

    from modb.database.cluster import ensure_writer_role

    with psycopg.connect(dsn, autocommit=True) as conn:
        ensure_writer_role(conn)
        skeleton = bandai_skeleton(conn)
    tokens = {}
    for name, role in (("clips-loader", "loader"), ("clips-reader", "reader")):
        r = run_modb(dsn, "token", "create", name, "--role", role, process=False)
        assert r.returncode == 0, r.stderr
        tokens[role] = {"Authorization": f"Bearer {r.stdout.strip()}"}
    body = {"skeleton": skeleton, "collection": "over rest", "fps": 30}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        url = "/api/collections/cmu/retarget"
        assert client.post(url, json=body, headers=tokens["reader"]).status_code == 403
        missing = client.post(
            "/api/collections/nowhere/retarget", json=body, headers=tokens["loader"]
        )
        assert missing.status_code == 404, missing.text
        r = client.post(url, json=body, headers=tokens["loader"])
        assert r.status_code == 202, r.text
        job_id = r.json()["id"]
        assert r.headers["location"] == f"/api/jobs/{job_id}"
        assert (r.json()["kind"], r.json()["submitter"]) == ("modb.retarget", "clips-loader")
        assert len(r.json()["arguments"]["clips"]) == len(TRIALS)
        w = worker(dsn)  # (one worker for both jobs)
        try:
            with connect(dsn) as conn:
                state = until(conn, job_id, lambda j: j["state"] == "done", 300, "done")
                made = clip_ids(conn, "over rest")
            assert sorted(c["clip_id"] for c in state["result"]["clips"]) == sorted(made)
            assert len(made) == len(TRIALS)
            # an edit script over a whole collection: a job too
            edit = {"collection": "over rest"}
            r = client.post("/api/edit-scripts/again/apply", json=edit, headers=tokens["loader"])
            assert r.status_code == 202 and r.json()["kind"] == "modb.apply_edit_script", r.text
            with connect(dsn) as conn:
                state = until(conn, r.json()["id"], lambda j: j["state"] == "done", 300, "done")
                versions = conn.execute(
                    "SELECT array_agg(version) FROM modb.current_clips "
                    "WHERE collection = 'over rest'"
                ).fetchone()[0]
        finally:
            stop(w)
        assert versions == [2] * len(TRIALS)
