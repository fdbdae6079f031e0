"""`modb bench actions` (issue 63, item 5) on one action and a few targets (the box's centre and
corners, out of reach): its table's figures for the target out of reach and its peak box, held
against the test's own computation: forward kinematics by scipy (support/own_kinematics) on the
frames the bench's synthesis makes (the same seed) and on the model's examples, the wrist's
distance to the target, the pose jumps against the examples' p99.9, the ankles' sliding and the
joints past the examples' range plus 10 degrees."""

from __future__ import annotations

import json
import os

import numpy as np
import psycopg
import pytest
from support import own_kinematics, shared
from support.bandai_actions import BUILT, GRAPH, build
from support.commands import run_modb_here as modb

from modb.bench import actions as bench
from modb.jobs.kernel_database import WorkerDatabase
from modb.models.examples import training_motions
from modb_kernel import model_synthesis

ACTION = "raise_right_hand"
SEED = 3


@pytest.fixture(scope="module")
def dsn(cluster):
    with shared.copy_of_built(cluster, BUILT, build, f"bench_actions_{os.getpid()}") as dsn:
        yield dsn


@pytest.fixture(scope="module")
def ran(dsn, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench_actions") / "figures.json"
    r = modb(dsn, "bench", "actions", "--models", GRAPH, "--actions", ACTION, "--groups",
             "inside,out", "--seed", SEED, "--json", out)  # fmt: skip
    assert r.returncode == 0, r.stderr
    return r.stdout, json.loads(out.read_text())["actions"]


def row(text: str, group: str) -> list[str]:
    (line,) = [x for x in text.splitlines() if x.startswith(f"| {group} |")]
    return [cell.strip() for cell in line.strip("|").split("|")]


def own_fk(rig, rotations, translations) -> np.ndarray:
    return own_kinematics.world_positions(rig.parents, rig.offsets, rig.translated, rotations,
                                          translations)  # fmt: skip


def own_jumps(p: np.ndarray, pelvis: int) -> np.ndarray:
    ground = p[:, pelvis].copy()
    ground[:, 1] = 0.0
    pose = p - ground[:, None]
    return np.max(np.linalg.norm(pose[1:] - pose[:-1], axis=-1), axis=1)


def own_sliding(p: np.ndarray, ankles: list[int]) -> float:
    return max(float(np.max(np.hypot(p[:, a, 0] - p[0, a, 0], p[:, a, 2] - p[0, a, 2])))
               for a in ankles)  # fmt: skip


def test_the_table_says_what_the_tests_own_kinematics_measure(dsn, ran):
    text, (figures,) = ran
    words = " ".join(text.split())  # the table's lines wrapped at 118 characters
    assert max(len(line) for line in text.splitlines()) <= 118
    assert f"{ACTION} (right): 24 examples" in words
    for group in ("inside", "out of reach", "all", "no target (baseline)"):
        assert row(text, group)
    assert "- met: out of reach said" in words and "within 1 cm wherever reachable" in words

    with psycopg.connect(dsn) as conn:
        graph, models, rig = model_synthesis.load(WorkerDatabase(conn), GRAPH)
        model = models[ACTION]
        examples = training_motions(conn, model.model, 1000)
        mirrored = {i for (i,) in conn.execute(
            "SELECT id FROM modb.processed_data WHERE mirrored").fetchall()}  # fmt: skip
    wrist, pelvis = rig.names.index("Hand_R"), rig.pelvis
    ankles = [rig.names.index(n) for n in ("Foot_L", "Foot_R")]

    # the examples: the captured ones' peaks' box (the mirrored left hands' left out), every
    # example's jumps' p99.9
    peaks, jumps = [], []
    for ident, m in examples:
        p = own_fk(rig, m.rotations, m.translations)
        if ident not in mirrored:
            peaks.append(p[int(np.argmax(p[:, wrist, 1])), wrist])
        jumps.append(own_jumps(p, pelvis))
    peaks = np.array(peaks)
    low, high = peaks.min(axis=0), peaks.max(axis=0)
    p999 = np.percentile(np.concatenate(jumps), 99.9)
    assert np.allclose(figures["box_low"], low, atol=1e-6)
    assert np.allclose(figures["box_high"], high, atol=1e-6)
    size = " x ".join(f"{100 * v:.0f}" for v in high - low)
    assert f"peak box {size} cm" in words and f"p99.9 {100 * p999:.2f} cm" in words
    centre = [t for t in figures["targets"] if t["label"] == "centre"][0]
    assert np.allclose(centre["local"], (low + high) / 2, atol=1e-9)

    # the target out of reach: its frames as the bench makes them, measured here
    (far,) = [t for t in figures["targets"] if t["group"] == "out of reach"]
    assert far["local"][2] == pytest.approx(1.2)
    syn, record, _ = bench.perform(graph, models, rig, ACTION, np.array(far["target"]), SEED)
    r, t = syn.frames()
    first, n = record["first_frame"], record["n_frames"]
    p = own_fk(rig, r[first - 1 : first + n], t[first - 1 : first + n])
    miss = np.linalg.norm(p[record["keyframe_frame"] - first + 1, wrist] - far["target"])
    cells = row(text, "out of reach")
    assert cells[1] == "1" and cells[5] == "0/1"
    ik = float(cells[4].split("/")[0])
    assert abs(ik - 100 * miss) <= 0.051 and miss > 0.3
    assert abs(float(cells[6]) - own_jumps(p, pelvis).max() / p999) <= 0.006
    assert abs(float(cells[7]) - 100 * own_sliding(p, ankles)) <= 0.006
    # joints past the examples' range + 10 degrees over the action's own frames once the seam from
    # standing has faded (0.4 s), the legs (pinned where it stands) left out (scipy's angles)
    mean = np.asarray(model.model["limits"]["mean"])
    degrees = np.asarray(model.model["limits"]["degrees"])
    own = r[first + round(0.4 * 30) : first + n]
    legs = {rig.names.index(f"{part}_{side}") for part in ("UpperLeg", "LowerLeg", "Foot")
            for side in "LR"}  # fmt: skip
    above = {rig.pelvis} | _ancestors(rig, rig.pelvis)
    past = 0
    for j in range(len(rig.names)):
        if j in above or j in legs:
            continue
        q = own_kinematics.rotations_of(own[:, j])
        m = own_kinematics.rotations_of(np.broadcast_to(mean[j], own[:, j].shape))
        past += int(np.degrees((m.inv() * q).magnitude()).max() > degrees[j] + 10.0)
    assert int(cells[8]) == past


def _ancestors(rig, j) -> set:
    out = set()
    while rig.parents[j] >= 0:
        j = rig.parents[j]
        out.add(j)
    return out


def test_an_action_not_in_the_graph_is_refused(dsn):
    r = modb(dsn, "bench", "actions", "--models", GRAPH, "--actions", "juggle")
    assert r.returncode == 2
    assert '"juggle" is not a reach action of the graph (its reach actions: ' in r.stderr


def test_an_action_where_the_character_starts_is_performed_without_a_walk(dsn):
    """The bench's case run whole (Synthesis.run): the action due at once, standing from the first
    frame (it once failed reading the pelvis of a body with no frames yet)."""
    with psycopg.connect(dsn) as conn:
        graph, models, rig = model_synthesis.load(WorkerDatabase(conn), GRAPH)
    target = [-0.1, 1.7, 0.15]
    syn = model_synthesis.Synthesis(graph, models, rig, [], 5.0, SEED, actions=[
        {"primitive": ACTION, "target": target, "stand": [0.0, 0.0]}]).run()  # fmt: skip
    (done,) = syn.actions
    assert done["reachable"] and done["ik_error_m"] <= 0.01 and not done["cut"], done
    assert not [s for s in syn.steps if s["node"] in ("left_step", "right_step")]
    r, t = syn.frames()
    p = own_fk(rig, r, t)
    assert np.linalg.norm(p[done["keyframe_frame"], rig.names.index("Hand_R")] - target) <= 0.01
