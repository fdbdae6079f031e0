"""Statistical motion models (issue 44) on CMU 16's walks and turns: built from the steps'
processed data, kept in versions, sampled in the server, exported, imported, served.

The quality report's figures are checked against the test's own computations: its own PCA (numpy's
SVD), B-spline evaluation (scipy's BSpline on the stored knots), forward kinematics and rotation
means (scipy's rotations), Gaussian likelihood (scipy.stats), contacts and nearest neighbours
(brute force), on the samples modb.sample_motion returns.

The model is conftest's cmu16_walks's model of the left steps, built there once per run with its
report (`modb model build --report-json`, its output kept): a copy of that database is the module's,
to write in. The `modb` command runs in this process (`process=False`): these tests are
about the models, not the command's process."""

from __future__ import annotations

import os
import time

import numpy as np
import psycopg
import pytest
from scipy.interpolate import BSpline
from scipy.stats import multivariate_normal
from sklearn.model_selection import KFold
from support import own_kinematics, shared
from support.commands import run_modb_here as modb
from support.databases import scratch_database
from support.gltf_validator import validate

from modb.database.connection import connect
from modb.models import build as B
from modb.models.examples import read_inputs, rig_of
from modb_kernel import motion_model

MODEL = "cmu16_left_step"


@pytest.fixture(scope="module")
def dsn(cmu16_walks):
    """CMU 16 loaded (collection cmu16), its steps annotated, MODEL and the right steps' model
    built, and the graph of models over them: a copy of conftest's cmu16_walks."""
    with cmu16_walks(f"models_{os.getpid()}") as dsn:
        yield dsn


@pytest.fixture(scope="module")
def report(dsn):
    """The report of MODEL's first build, which aligned the left steps first (conftest's
    cmu16_walks built MODEL right after finding the steps, and kept what it printed)."""
    build = shared.kept(MODEL)
    assert "aligning 'left_step' in 'cmu16' first: it has no processed data" in build["stderr"]
    assert f"model {MODEL} version 1 " in build["stdout"]
    assert "meets the quality targets" in build["stdout"]
    return build["report"]


def stored(conn, version=None):
    return conn.execute(
        "SELECT data, meta FROM modb.models WHERE name = %s "
        "AND (%s::int IS NULL OR version = %s) ORDER BY version DESC LIMIT 1",
        [MODEL, version, version],
    ).fetchone()


def own_frames(model, flat):
    """(rotations, translations) of flattened coefficients: scipy's B-splines on the stored knots,
    the lever-arm weights taken off, quaternions normalised."""
    spatial = model["spatial"]
    k, n = spatial["n_basis"], model["n_frames"]
    coef = np.asarray(flat).reshape(k, -1)
    channels = BSpline(np.asarray(spatial["knots"]), coef, 3)(np.arange(n, dtype=float))
    nt = len(model["translated"])
    rotations = channels[:, 3 * nt :].reshape(n, -1, 4) / np.asarray(spatial["weights"])[:, None]
    rotations /= np.linalg.norm(rotations, axis=-1, keepdims=True)
    return rotations, channels[:, : 3 * nt].reshape(n, nt, 3)


def own_pca_rebuild(rows, row, keep):
    """row projected on the principal axes of rows that keep `keep` of their variance, and back."""
    mean = rows.mean(axis=0)
    _, s, vt = np.linalg.svd(rows - mean, full_matrices=False)
    share = np.cumsum(s**2) / np.sum(s**2)
    axes = vt[: int(np.searchsorted(share, keep, side="right")) + 1]
    return mean + (row - mean) @ axes.T @ axes


def own_played(rotations, translations, times):
    """Canonical frames played at the example's own frames (times: its frame at each canonical
    frame), by linear interpolation and renormalisation."""
    at = np.interp(np.arange(int(np.floor(times[-1] + 1e-9)) + 1), times, np.arange(len(times)))
    lo = np.minimum(np.floor(at).astype(int), len(times) - 2)
    w = (at - lo)[:, None, None]
    hi = (
        rotations[lo + 1]
        * np.where(np.sum(rotations[lo + 1] * rotations[lo], -1) < 0, -1, 1)[..., None]
    )
    r = rotations[lo] * (1 - w) + hi * w
    return r / np.linalg.norm(r, axis=-1, keepdims=True), translations[lo] * (1 - w) + translations[
        lo + 1
    ] * w


def test_the_report_meets_the_targets_by_the_tests_own_measures(dsn, report):
    assert report["pass"] and report["examples"] > 100 and report["mirrored_examples"] > 50
    assert report["mixture_components"] >= 1 and report["mixture_bic"]
    with connect(dsn) as conn:
        model, _ = stored(conn)
        inputs = read_inputs(conn, "cmu16", "left_step")
        with conn.cursor(binary=True) as cur:
            samples = cur.execute(
                "SELECT rotations, translations FROM modb.sample_motion(%s, 100, 0, 1) "
                "ORDER BY sample",
                [MODEL],
            ).fetchall()
    sk = inputs.skeleton

    def fk(rotations, translations):
        return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, rotations,
                                              translations)  # fmt: skip

    forward = [B.facing_forward(e, rig_of(sk), inputs.fps) for e in inputs.examples]
    rows = B.spatial_rows(
        forward, np.asarray(model["spatial"]["weights"]), model["spatial"]["n_basis"]
    )

    # reconstruction, left out one at a time, against the others' mean motion
    r = report["reconstruction"]
    held = np.unique(np.linspace(0, len(rows) - 1, r["held_out"]).round().astype(int))
    errors, mean_errors = [], []
    for k in held:
        others = np.delete(rows, k, axis=0)
        truth = fk(forward[k].rotations, forward[k].translations)
        rebuilt = own_pca_rebuild(others, rows[k], model["settings"]["variance_kept"])
        errors.append(np.linalg.norm(fk(*own_frames(model, rebuilt)) - truth, axis=-1).mean(0))
        guess = fk(*own_frames(model, others.mean(axis=0)))
        mean_errors.append(np.linalg.norm(guess - truth, axis=-1).mean(0))
    joint_error, joint_mean = 100 * np.mean(errors, 0), 100 * np.mean(mean_errors, 0)
    assert r["error_cm"] == pytest.approx(joint_error.mean(), rel=1e-3)
    assert r["mean_motion_error_cm"] == pytest.approx(joint_mean.mean(), rel=1e-3)
    assert joint_error.mean() <= 0.5 * joint_mean.mean()
    moving = joint_mean > 1.0
    assert np.all(joint_error[moving] <= 0.5 * joint_mean[moving]), sk.names

    # held-out likelihood: the mixture at least a single Gaussian's, fitted by the test
    spatial, temporal = model["spatial"], model["temporal"]
    scores = np.hstack([
        (rows - spatial["mean"]) @ np.asarray(spatial["components"]).T,
        (B.temporal_rows(forward, temporal["n_basis"]) - temporal["mean"])
        @ np.asarray(temporal["components"]).T,
    ])  # fmt: skip
    single = []
    for train, test in KFold(5, shuffle=True, random_state=0).split(scores):
        cov = np.cov(scores[train], rowvar=False, bias=True) + 1e-6 * np.eye(scores.shape[1])
        single.extend(multivariate_normal(scores[train].mean(0), cov).logpdf(scores[test]))
    assert report["likelihood"]["single_gaussian"] == pytest.approx(np.mean(single), rel=1e-3)
    assert report["likelihood"]["mixture"] >= np.mean(single)

    # samples (the server's): foot sliding near the ground against the training examples'
    played = [fk(*own_played(e.rotations, e.translations, e.time_function)) for e in forward]
    drawn = [fk(np.asarray(r_, float), np.asarray(t_, float)) for r_, t_ in samples]
    feet = {s: [sk.names.index(sk.joint_map[f"{s}_{p}"]) for p in ("ankle", "toe")]
            for s in ("left", "right")}  # fmt: skip
    rest = fk(
        np.tile([1.0, 0, 0, 0], (1, len(sk.parents), 1)), np.zeros((1, len(sk.translated), 3))
    )[0]
    leg = np.mean([
        np.linalg.norm(rest[sk.names.index(sk.joint_map[f"{s}_hip"])]
                       - rest[sk.names.index(sk.joint_map[f"{s}_knee"])])
        + np.linalg.norm(rest[sk.names.index(sk.joint_map[f"{s}_knee"])]
                         - rest[sk.names.index(sk.joint_map[f"{s}_ankle"])])
        for s in feet
    ])  # fmt: skip
    ground = np.percentile(
        np.concatenate([p[:, feet[s], 1].min(1) for p in played for s in feet]), 5
    )

    def sliding(motions):
        speeds = []
        for p in motions:
            for s, (ankle, toe) in feet.items():
                flat = p[:, [ankle, toe]][..., [0, 2]]
                speed = np.linalg.norm(np.gradient(flat, axis=0), axis=-1).min(1) * inputs.fps
                speeds.append(speed[p[:, [ankle, toe], 1].min(1) < ground + 0.1 * leg])
        return np.mean(np.concatenate(speeds))

    ratio = sliding(drawn) / sliding(played)
    assert ratio <= 1.5 and ratio == pytest.approx(report["foot_sliding"]["ratio"], rel=0.1)

    # every animated joint within 10% of the training examples' farthest turn from its mean
    training = np.concatenate([e.rotations for e in forward])
    sampled = np.concatenate([np.asarray(r_, float) for r_, _ in samples])
    for j in range(len(sk.parents)):
        mean = own_kinematics.rotations_of(training[:, j]).mean()
        reach = np.degrees(
            (mean.inv() * own_kinematics.rotations_of(training[:, j])).magnitude()
        ).max()
        turned = np.degrees((mean.inv() * own_kinematics.rotations_of(sampled[:, j])).magnitude())
        if reach >= 1.0:
            assert turned.max() <= 1.1 * reach + 1e-6, (sk.names[j], turned.max(), reach)

    # novelty: a sample's nearest training example against the examples' own nearest neighbour
    split = len(spatial["components"])
    canonical = np.stack([fk(e.rotations, e.translations) for e in forward])
    new = np.stack([fk(*motion_model.canonical_frames(model, d[:split]))
                    for d in motion_model.draw_scores(model["mixture"], 100, 0)])  # fmt: skip

    def rms(a, others):
        """cm: the root mean square over frames and joints of a's distance to each of others."""
        return np.sqrt(np.mean(np.sum((others - a) ** 2, axis=-1), axis=(1, 2))) * 100

    own = [np.delete(rms(c, canonical), i).min() for i, c in enumerate(canonical)]
    nearest = [rms(s, canonical).min() for s in new]
    assert report["novelty"]["training_nn_cm"] == pytest.approx(np.median(own), rel=1e-6)
    assert report["novelty"]["samples_nn_cm"] == pytest.approx(np.median(nearest), rel=1e-6)
    assert 0.5 <= np.median(nearest) / np.median(own) <= 2.0


def test_sample_motion_in_sql_glb_and_bvh_files(dsn, report, tmp_path):
    with psycopg.connect(dsn) as conn:
        first = conn.execute("SELECT * FROM modb.sample_motion(%s, 3, 7)", [MODEL]).fetchall()
        again = conn.execute("SELECT * FROM modb.sample_motion(%s, 3, 7, 1)", [MODEL]).fetchall()
        other = conn.execute("SELECT * FROM modb.sample_motion(%s, 3, 8)", [MODEL]).fetchall()
        assert first == again and first != other and [r[0] for r in first] == [1, 2, 3]
        sample, fps, n_frames, rotations, translations = first[0]
        joints = conn.execute(
            "SELECT jsonb_array_length(hierarchy->'joints') FROM modb.skeletons"
        ).fetchone()[0]
        assert fps == 120 and np.asarray(rotations).shape == (n_frames, joints, 4)
        assert np.allclose(np.linalg.norm(rotations, axis=-1), 1, atol=1e-6)
        for args, message in (((MODEL, 0, 1), "n is 0: ask for 1 to 1000 samples"),
                              ((MODEL, 1, -1), "seed is -1"),
                              (("nope", 1, 1), 'no motion model "nope"')):  # fmt: skip
            with pytest.raises(psycopg.Error, match=message):
                conn.execute("SELECT * FROM modb.sample_motion(%s, %s, %s)", args)
            conn.rollback()
        conn.execute("SET ROLE modb_reader")  # a read-only role samples
        assert (
            len(conn.execute("SELECT * FROM modb.sample_motion(%s, 2, 1)", [MODEL]).fetchall()) == 2
        )
    r = modb(dsn, "model", "sample", MODEL, "-n", "10", "--seed", "3", "--out", tmp_path / "s.glb")
    assert r.returncode == 0, r.stderr
    issues = validate(tmp_path / "s.glb")
    assert issues["numErrors"] == 0, issues["messages"]
    import pygltflib

    assert len(pygltflib.GLTF2.load(str(tmp_path / "s.glb")).animations) == 10
    r = modb(dsn, "model", "sample", MODEL, "-n", "3", "--out", tmp_path / "s.bvh")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.glob("s_*.bvh")) == ["s_01.bvh", "s_02.bvh", "s_03.bvh"]
    r = modb(dsn, "model", "sample", MODEL, "--out", tmp_path / "s.txt")
    assert r.returncode == 2 and "name a .bvh, .glb or .gltf file" in r.stderr


def test_versions_reproducible_builds_staleness_export_and_import(dsn, report, tmp_path, cluster):
    for collection, primitive, message in (
        ("cmu16", "jump", 'collection "cmu16" has 0 "jump" segments: aligning needs at least 5'),
        ("nope", "left_step", 'no collection "nope"'),
    ):
        r = modb(dsn, "model", "build", "x", "--collection", collection, "--primitive", primitive)
        assert r.returncode == 2 and message in r.stderr, r.stderr
    r = modb(dsn, "model", "build", MODEL, "--collection", "cmu16", "--primitive", "left_step")
    assert r.returncode == 0 and f"model {MODEL} version 2 " in r.stdout, r.stderr
    with connect(dsn) as conn:
        (v1, meta1), (v2, meta2) = stored(conn, 1), stored(conn, 2)
        # the same seed, the same model and tree (each version may name the job that built it)
        assert v1 == v2 and meta1["tree"] == meta2["tree"]
        with pytest.raises(psycopg.errors.ObjectNotInPrerequisiteState, match="only its meta"):
            conn.execute("UPDATE modb.models SET data = '{}' WHERE name = %s", [MODEL])
        conn.execute(
            "UPDATE modb.models SET meta = meta || '{\"note\": 1}' WHERE name = %s", [MODEL]
        )
    r = modb(dsn, "model", "list")
    assert f"{MODEL} v1: left_step of cmu16" in r.stdout and f"{MODEL} v2 (latest)" in r.stdout
    assert "stale" not in r.stdout
    r = modb(dsn, "model", "export", MODEL, "--version", "1", "--out", tmp_path / "m.json")
    assert r.returncode == 0, r.stderr
    r = modb(dsn, "model", "import", tmp_path / "m.json", "--name", "walk_left_copy")
    assert r.returncode == 0 and "model walk_left_copy version 1" in r.stdout, r.stderr
    with connect(dsn) as conn:
        copied = conn.execute(
            "SELECT data FROM modb.models WHERE name = 'walk_left_copy'"
        ).fetchone()[0]
        assert copied == v1
        # an example's segment is gone: the models built from it are stale, a rebuild aligns first
        conn.execute(
            "UPDATE modb.clip_versions v SET meta = jsonb_set(v.meta, '{annotations}', "
            "(v.meta->'annotations') - 0) "
            "FROM modb.processed_data p WHERE p.clip_id = v.clip_id AND p.version = v.version "
            "AND p.id = (SELECT min(id) FROM modb.processed_data WHERE primitive = 'left_step')"
        )
        stale = dict(conn.execute("SELECT version, stale FROM modb.model_status WHERE name = %s",
                                  [MODEL]).fetchall())  # fmt: skip
        assert stale == {1: stale[1], 2: stale[2]} and all(
            s.startswith("processed data it was built from is stale") for s in stale.values()
        ), stale
    r = modb(dsn, "model", "build", MODEL, "--collection", "cmu16", "--primitive", "left_step")
    assert r.returncode == 0 and "version 3" in r.stdout, r.stderr
    assert "first: its processed data is stale" in r.stderr
    r = modb(dsn, "model", "list", "--collection", "cmu16")
    assert f"{MODEL} v3 (latest)" in r.stdout and "stale: processed data" in r.stdout
    with connect(dsn) as conn:
        assert conn.execute(
            "SELECT stale FROM modb.model_status WHERE name = %s AND version = 3", [MODEL]
        ).fetchone() == (None,)
    r = modb(dsn, "model", "delete", MODEL, "--version", "2")
    assert r.returncode == 0 and "deleted 1 version of model" in r.stdout
    r = modb(dsn, "model", "show", MODEL, "--version", "2")
    assert r.returncode == 2 and f'no motion model "{MODEL}" version 2' in r.stderr
    # a database without the skeleton refuses the file, saying what to do
    with scratch_database(cluster, f"models_empty_{os.getpid()}") as empty:
        r = modb(empty, "model", "import", tmp_path / "m.json")
        assert r.returncode == 2 and "load a clip of that skeleton first" in r.stderr
    (tmp_path / "bad.json").write_text('{"format": "modb motion model",\n "data": [}')
    r = modb(dsn, "model", "import", tmp_path / "bad.json")
    assert r.returncode == 2 and "bad.json: line 2: not JSON" in r.stderr


def test_rest_lists_shows_samples_and_builds_with_a_loader_token(dsn, report):
    import httpx
    from support.browser import serving
    from support.jobs import stop, until, worker

    tokens = {}
    for name, role in (("models-loader", "loader"), ("models-reader", "reader")):
        r = modb(dsn, "token", "create", name, "--role", role)
        assert r.returncode == 0, r.stderr
        tokens[role] = {"Authorization": f"Bearer {r.stdout.strip()}"}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=120) as client:
        listed = client.get("/api/motion-models", params={"collection": "cmu16"},
                            headers=tokens["reader"]).json()  # fmt: skip
        assert {m["name"] for m in listed} >= {MODEL}
        shown = client.get(f"/api/motion-models/{MODEL}", headers=tokens["reader"]).json()
        with psycopg.connect(dsn) as conn:
            latest = conn.execute(
                "SELECT version, jsonb_array_length(data->'inputs'), "
                "jsonb_array_length(data->'spatial'->'components') FROM modb.models "
                "WHERE name = %s ORDER BY version DESC LIMIT 1",
                [MODEL],
            ).fetchone()
        assert (shown["version"], shown["examples"], len(shown["spatial_explained"])) == latest
        got = client.get(f"/api/motion-models/{MODEL}/samples",
                         params={"n": 2, "seed": 7}, headers=tokens["reader"]).json()  # fmt: skip
        with psycopg.connect(dsn) as conn:
            sql_rotations = conn.execute(
                "SELECT rotations FROM modb.sample_motion(%s, 2, 7, %s) ORDER BY sample",
                [MODEL, shown["version"]],
            ).fetchall()
        # the server's connection that sampled is closed, not kept growing (issue 58, 9)
        for _ in range(50):
            with psycopg.connect(dsn) as conn:
                kept = conn.execute(
                    "SELECT count(*) FROM pg_stat_activity WHERE state = 'idle' "
                    "AND query LIKE '%%sample_motion%%' AND pid <> pg_backend_pid()"
                ).fetchone()[0]
            if kept == 0:
                break
            time.sleep(0.1)
        assert kept == 0, "a server connection that sampled went back to the pool"
        for s, (rotations,) in zip(got["samples"], sql_rotations, strict=True):
            assert np.allclose(s["rotations"], rotations, atol=1e-6)
            positions = own_kinematics.world_positions(got["parents"], *_offsets(dsn, got),
                                                       np.asarray(s["rotations"]),
                                                       np.asarray(s["translations"]))  # fmt: skip
            assert np.allclose(s["positions"], positions, atol=1e-4)
        examples = client.get(f"/api/motion-models/{MODEL}/examples", params={"n": 3},
                              headers=tokens["reader"]).json()["examples"]  # fmt: skip
        assert len(examples) == 3 and all(e["n_frames"] > 10 for e in examples)
        body = {"collection": "cmu16", "primitive": "right_step"}
        path = "/api/motion-models/walk_right/build"
        assert client.post(path, json=body, headers=tokens["reader"]).status_code == 403
        bad = client.post(path, json={**body, "variance": 2}, headers=tokens["loader"])
        assert bad.status_code == 400 and "variance" in bad.text
        made = client.post(path, json=body, headers=tokens["loader"])  # no job tables: at once
        assert made.status_code == 201 and made.json()["version"] == 1, made.text
        r = modb(dsn, "worker", "--init")
        assert r.returncode == 0, r.stderr
        queued = client.post(path, json={**body, "report": True}, headers=tokens["loader"])
        assert queued.status_code == 202, queued.text
        assert queued.json()["kind"] == "modb.build_model"
        w = worker(dsn)
        try:
            with connect(dsn) as conn:
                job_id = queued.json()["id"]
                state = until(conn, job_id, lambda j: j["state"] == "done", 120, "done")
        finally:
            stop(w)
        assert state["result"]["version"] == 2 and state["result"]["report"]["pass"], state
        # a generic replace of a model row is its next version, the old kept
        ident = listed[0]["id"]
        junk = client.put(f"/api/models/{ident}", json={"data": {"note": "by hand"}},
                          headers=tokens["loader"])  # fmt: skip
        assert junk.status_code == 400 and '"fps"' in junk.json()["error"], junk.text  # issue 58
        data = client.get(f"/api/models/{ident}", headers=tokens["reader"]).json()["data"]
        noted = {**data, "settings": {**data["settings"], "note": "by hand"}}
        replaced = client.put(f"/api/models/{ident}", json={"data": noted},
                              headers=tokens["loader"])  # fmt: skip
        assert replaced.status_code == 201 and replaced.json()["previous"] == ident, replaced.text
        assert client.get(f"/api/models/{ident}", headers=tokens["reader"]).json()["data"] == data


def _offsets(dsn, answer):
    with psycopg.connect(dsn) as conn:
        hierarchy = conn.execute(
            "SELECT hierarchy FROM modb.skeletons WHERE id = %s", [answer["skeleton_id"]]
        ).fetchone()[0]
    return [j["offset"] for j in hierarchy["joints"]], answer["translated"]
