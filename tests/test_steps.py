"""Steps from foot contacts and their examples aligned in time (issue 43), on the shipped walks.

Checked against the test's own computations: foot contacts found by its own forward kinematics
(scipy's rotations) and its own run cleaning, on every shipped walk (Bandai dataset 1's and 2's
walks and walk-turns, CMU 16's trials); the warp's cost against a brute-force search of every path
on small cases; aligned frames against the source frames resampled by the time function with the
test's own slerp (scipy's).

The `modb` command runs in this process (`process=False`): these tests are about the steps and the
data, not the command's process."""

from __future__ import annotations

import json
import os

import numpy as np
import psycopg
import pytest
from scipy.spatial.transform import Rotation, Slerp
from support.commands import run_modb_here as modb
from support.data import mocap
from support.own_steps import SIDES, own_contacts, own_steps, own_touchdowns
from support.databases import scratch_database

from modb.clips import read_motion
from modb.database.connection import connect
from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb_kernel import align as kernel_align
from modb_kernel import mirror as kernel_mirror
from modb_kernel import primitives as kernel_primitives
from modb_kernel import steps as kernel_steps



def shipped_walks():
    bandai = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk*.bvh"))
    bandai += sorted(mocap("bandai-1", "data").glob("dataset-1_walk*.bvh"))
    asf = read_asf(str(mocap("cmu", "16", "16.asf")))
    cmu = [read_amc(str(p), asf) for p in sorted(mocap("cmu", "16").glob("16_*.amc"))]
    return [read_bvh(str(p)) for p in bandai] + cmu


def kernel_found(motion):
    sk = motion.skeleton
    return kernel_steps.find(sk.parents, sk.offsets, motion.rotations, motion.translations,
                             sk.translated, sk.names, sk.joint_map, motion.fps)  # fmt: skip


def test_steps_on_every_shipped_walk_match_an_independent_detection():
    walks = shipped_walks()
    assert len(walks) > 300
    total = 0
    for motion in walks:
        found, _ = kernel_found(motion)
        oracle_contacts = own_contacts(motion)
        oracle = own_steps(oracle_contacts, motion.fps)
        assert abs(len(found) - len(oracle)) <= 1, (motion.name, found, oracle)
        touchdowns = {s: own_touchdowns(oracle_contacts[s]) for s in SIDES}
        for name, start, end in found:
            swing = name.split("_")[0]
            planted = "right" if swing == "left" else "left"
            for side, frame in ((planted, start), (swing, end)):
                nearest = min((abs(frame - t) for t in touchdowns[side]), default=99)
                assert nearest <= 2, (motion.name, name, start, end, side, touchdowns[side])
        total += len(found)
    assert total > 8 * len(walks)  # walks have steps: the detection is not silent


# --- dynamic time warping against a brute-force search ------------------------------------------


def brute_force_cost(costs):
    """The least cost of any path from (0, 0) to the end with moves (1, 0), (0, 1), (1, 1)."""
    n, m = costs.shape
    best = np.inf

    def walk(i, j, total):
        nonlocal best
        total += costs[i, j]
        if (i, j) == (n - 1, m - 1):
            best = min(best, total)
            return
        for di, dj in ((1, 0), (0, 1), (1, 1)):
            if i + di < n and j + dj < m:
                walk(i + di, j + dj, total)

    walk(0, 0, 0.0)
    return best


def test_the_warp_is_the_cheapest_path_of_a_brute_force_search():
    rng = np.random.default_rng(43)
    for n, m in [(1, 1), (2, 3), (4, 4), (5, 3), (3, 6), (6, 5)]:
        for _ in range(5):
            costs = rng.random((n, m))
            cost, path = kernel_align.warp(costs)
            assert cost == pytest.approx(brute_force_cost(costs), abs=1e-12)
            assert path[0] == (0, 0) and path[-1] == (n - 1, m - 1)
            assert all(
                (b[0] - a[0], b[1] - a[1]) in ((1, 0), (0, 1), (1, 1))
                for a, b in zip(path, path[1:])
            )
            assert sum(costs[i, j] for i, j in path) == pytest.approx(cost, abs=1e-12)


# --- in the database ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dsn(cluster):
    with scratch_database(cluster, f"steps_{os.getpid()}") as dsn:
        # no snippets: nothing here selects them
        r = modb(dsn, "load", mocap("cmu", "16"), "--collection", "cmu16", "--no-snippets", "-q")
        assert r.returncode == 0, r.stderr
        walks = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[:6]
        r = modb(dsn, "load", *map(str, walks), "--collection", "bandai", "--no-snippets", "-q")
        assert r.returncode == 0, r.stderr
        yield dsn


def stored_segments(conn, clip):
    return (
        conn.execute(
            "SELECT v.meta->'annotations' FROM modb.current_clips c "
            "JOIN modb.clip_versions v USING (clip_id, version) WHERE c.clip_id = %s",
            [clip],
        ).fetchone()[0]
        or []
    )


def test_annotate_steps_writes_automatic_segments_and_keeps_a_persons(dsn):
    r = modb(dsn, "annotate", "--steps", "cmu16", "bandai")
    assert r.returncode == 0, r.stderr
    assert "34 clips: " in r.stdout, r.stdout
    with connect(dsn) as conn:
        clips = [
            c for (c,) in conn.execute("SELECT clip_id FROM modb.current_clips ORDER BY clip_id")
        ]
        for clip in clips:  # what is stored is what the kernel finds on the stored frames
            motion = read_motion(conn, clip)
            sk = motion.skeleton
            found = kernel_primitives.find(sk.parents, sk.offsets, motion.rotations,
                                           motion.translations, sk.translated, sk.names,
                                           sk.joint_map, motion.fps)  # fmt: skip
            stored = stored_segments(conn, clip)
            assert [(a["name"], a["start"], a["end"], a["keyframes"]) for a in stored] == found
            steps, _ = kernel_found(motion)  # the steps among them, as steps.py finds them
            assert [(a["name"], a["start"], a["end"]) for a in stored
                    if a["name"] in ("left_step", "right_step")] == steps  # fmt: skip
            assert all(a["auto"] is True and a["keyframes"][0] == a["start"]
                       and a["keyframes"][-1] == a["end"] for a in stored)  # fmt: skip
        clip = clips[0]
        before = stored_segments(conn, clip)
    # a person's segment, and an automatic one a person edited (the editor drops the mark)
    edited = dict(before[0], end=before[0]["end"] - 1, keyframes=[before[0]["start"]])
    del edited["auto"]
    mine = {"name": "walk", "start": 0, "end": 40}
    with connect(dsn) as conn:
        conn.execute(
            "UPDATE modb.clip_versions v SET meta = jsonb_set(v.meta, '{annotations}', %s) "
            "FROM modb.current_clips c WHERE c.clip_id = v.clip_id AND c.version = v.version "
            "AND c.clip_id = %s",
            [psycopg.types.json.Jsonb([mine, edited, *before[1:]]), clip],
        )
    r = modb(dsn, "annotate", "--steps", f"id:{clip}")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        after = stored_segments(conn, clip)
    assert mine in after and edited in after
    assert sorted(map(json.dumps, [a for a in after if a.get("auto")])) == sorted(
        map(json.dumps, before)
    )


def test_alignment_lands_keyframes_and_resamples_the_source(dsn):
    r = modb(dsn, "annotate", "--steps", "cmu16")
    assert r.returncode == 0, r.stderr
    r = modb(dsn, "align", "left_step", "--collection", "cmu16")
    assert r.returncode == 0, r.stderr
    assert "left_step in cmu16: " in r.stdout and " stale rows deleted" in r.stdout
    with connect(dsn) as conn:
        rows = conn.execute(
            "SELECT clip_id, version, segment, reference, n_frames, time_function, sections, "
            "rotations, mirrored FROM modb.processed_data WHERE primitive = 'left_step' ORDER BY id"
        ).fetchall()
        lengths = [s["end"] - s["start"] + 1 for _, _, s, *_ in rows]
        captured = [n for n, row in zip(lengths, rows) if not row[-1]]
        (reference,) = [k for k, row in enumerate(rows) if row[3]]
        # the reference: the captured example whose length is closest to the mean
        assert not rows[reference][-1] and abs(lengths[reference] - np.mean(captured)) == min(
            abs(np.array(captured) - np.mean(captured))
        )
        # the right steps, mirrored, are left steps too (CMU 16's skeleton has mirror pairs)
        assert {row[2]["name"] for row in rows if row[-1]} == {"right_step"}
        assert {row[2]["name"] for row in rows if not row[-1]} == {"left_step"}
        motions = {}
        for clip, version, segment, is_reference, n, times, sections, rotations, mirrored in rows:
            times, rotations = np.asarray(times), np.asarray(rotations)  # once, not per joint
            span = segment["end"] - segment["start"]
            assert n == lengths[reference] and len(times) == n
            assert np.all(np.diff(times) >= 0) and times[0] >= 0 and times[-1] <= span
            for reference_key, example_key in zip(sections, segment["keyframes"]):
                assert abs(times[reference_key] - (example_key - segment["start"])) <= 1
            if is_reference:
                assert np.allclose(times, np.arange(n))
            motion = motions.setdefault(clip, read_motion(conn, clip, version))
            cut = slice(segment["start"], segment["end"] + 1)
            source = motion.rotations[cut]
            if mirrored:  # the kernel's mirror (tests/test_mirror.py checks it) of the segment
                sk = motion.skeleton
                source, _ = kernel_mirror.mirror(
                    sk.parents, sk.offsets, [j.end_site for j in sk.joints],
                    kernel_mirror.partner_index(sk.names, sk.mirror_pairs), source,
                    motion.translations[cut], sk.translated,
                )  # fmt: skip
            for j in range(source.shape[1]):  # the test's own slerp of each joint's rotations
                w, x, y, z = np.moveaxis(source[:, j], -1, 0)
                slerp = Slerp(
                    np.arange(len(source)), Rotation.from_quat(np.stack([x, y, z, w], -1))
                )
                own = slerp(times).as_quat()
                theirs = np.asarray(rotations)[:, j]
                theirs = np.stack([theirs[:, 1], theirs[:, 2], theirs[:, 3], theirs[:, 0]], -1)
                dots = np.abs(np.sum(own * theirs, axis=-1))
                assert np.all(dots > 1 - 1e-6), (clip, j, dots.min())
        assert len(rows) >= 40


def test_stale_rows_say_so_and_aligning_again_redoes_only_them(dsn):
    with connect(dsn) as conn:
        clip, start, end = conn.execute(
            "SELECT clip_id, start_frame, end_frame FROM modb.processed_data_status "
            "WHERE primitive = 'left_step' AND NOT reference ORDER BY id LIMIT 1"
        ).fetchone()
        n_rows = conn.execute(
            "SELECT count(*) FROM modb.processed_data WHERE primitive = 'left_step'"
        ).fetchone()[0]
    r = modb(dsn, "annotate", f"id:{clip}", "--remove", f"left_step:{start}-{end}")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        assert conn.execute(
            "SELECT stale FROM modb.processed_data_status WHERE clip_id = %s AND start_frame = %s",
            [clip, start],
        ).fetchone() == ("its segment changed or is gone",)
    r = modb(dsn, "align", "left_step", "--collection", "cmu16")
    assert r.returncode == 0, r.stderr
    assert f"{n_rows - 1} examples, 0 aligned now, 1 stale rows deleted" in r.stdout, r.stdout
    r = modb(dsn, "align", "jump", "--collection", "cmu16")
    assert r.returncode == 2 and 'has 0 "jump" segments: aligning needs at least 5' in r.stderr


def test_rest_finds_steps_and_aligns_as_jobs_and_reads_processed_data(dsn):
    import httpx
    from support.browser import serving
    from support.jobs import stop, until, worker

    from modb.database.cluster import ensure_writer_role

    with psycopg.connect(dsn, autocommit=True) as conn:
        ensure_writer_role(conn)
        clip = conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'bandai' ORDER BY clip_id"
        ).fetchone()[0]
    tokens = {}
    for name, role in (("steps-loader", "loader"), ("steps-reader", "reader")):
        r = modb(dsn, "token", "create", name, "--role", role)
        assert r.returncode == 0, r.stderr
        tokens[role] = {"Authorization": f"Bearer {r.stdout.strip()}"}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        assert client.post(f"/api/clips/{clip}/steps", headers=tokens["reader"]).status_code == 403
        r = client.post(f"/api/clips/{clip}/steps", headers=tokens["loader"])
        assert r.status_code == 200, r.text
        assert r.json()["steps"] and all(
            s["keyframes"] == [s["start"], s["end"]] for s in r.json()["steps"]
        )
        r = modb(dsn, "worker", "--init")
        assert r.returncode == 0, r.stderr
        found = client.post("/api/collections/bandai/steps", headers=tokens["loader"])
        assert found.status_code == 202 and found.json()["kind"] == "modb.annotate_steps", (
            found.text
        )
        body = {"primitive": "right_step", "collection": "bandai"}
        aligned = client.post("/api/processed-data", json=body, headers=tokens["loader"])
        assert aligned.status_code == 202, aligned.text
        assert client.post(
            "/api/jobs", json={"kind": "align", "arguments": body, "after": [aligned.json()["id"]]},
            headers=tokens["reader"],
        ).status_code == 403  # fmt: skip
        w = worker(dsn)
        try:
            with connect(dsn) as conn:
                until(conn, found.json()["id"], lambda j: j["state"] == "done", 60, "done")
                state = until(
                    conn, aligned.json()["id"], lambda j: j["state"] == "done", 60, "done"
                )
        finally:
            stop(w)
        assert state["result"]["examples"] == state["result"]["aligned"] >= 5
        rows = client.get("/api/processed-data", params=body).json()
        assert len(rows) == state["result"]["examples"] and sum(r["reference"] for r in rows) == 1
        assert all(r["stale"] is None for r in rows)
        one = client.get(f"/api/processed-data/{rows[0]['id']}").json()
        assert len(one["time_function"]) == one["n_frames"] == len(one["rotations"])


def test_a_rig_without_toes_stands_on_its_ankles():
    from dataclasses import replace

    for path in sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[:5]:
        motion = read_bvh(str(path))
        toeless = {k: v for k, v in motion.skeleton.joint_map.items() if not k.endswith("_toe")}
        found, _ = kernel_found(motion)
        ankles, _ = kernel_found(
            replace(motion, skeleton=replace(motion.skeleton, joint_map=toeless))
        )
        assert abs(len(ankles) - len(found)) <= 2 and len(ankles) >= 8, (path.name, found, ankles)
        # standing on the ankles finds a foot planted twice in one swing: not a step (issue 58)
        shortest = min((end - start) / motion.fps for _, start, end in ankles)
        assert shortest >= 0.2, (path.name, ankles)


def test_no_step_is_shorter_than_a_person_can_take():
    """CMU 131_01 (120 fps, stylised walking) once gave right steps of 2 frames (17 ms)."""
    asf = read_asf(str(mocap("cmu", "131", "131.asf")))
    motion = read_amc(str(mocap("cmu", "131", "131_01.amc")), asf)
    found, contact = kernel_found(motion)
    lengths = [(end - start) / motion.fps for _, start, end in found]
    assert found and min(lengths) >= 0.2, found
    # touchdowns of alternate feet closer than 0.2 s are there: the case is met, and passed over
    events = sorted((f, s) for s in SIDES for f in own_touchdowns(contact[s]))
    close = [(a, b) for a, b in zip(events, events[1:]) if a[1] != b[1] and b[0] - a[0] < 24]
    assert close, "131_01 has no touchdowns closer than 0.2 s: the case is not tested here"
    assert found == own_steps(contact, motion.fps)
