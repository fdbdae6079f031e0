"""Actions in a synthesis from models (issue 63): modb.synthesize_from_models(..., actions) and
`modb synth --models --action` walk to the place of each action, come to rest, perform it with the
hand meeting its target and stand again. Judged by the tests' own kinematics (scipy) on the frames
returned, against held-out capture of the same actions: the wrist at the target, the feet planted,
each joint within the examples' range plus 10 degrees, the elbow bent as the examples bend it, no
pose jump above the capture's p99.9; an unreachable target said so; goals and actions in order; a
wave facing its point for the time asked; an action cut by the strip's end said so."""

from __future__ import annotations

import json
import os

import numpy as np
import psycopg
import pytest
from psycopg.types.json import Jsonb
from support import own_kinematics, shared
from support.bandai_actions import BUILT, GRAPH, action_files, build
from support.browser import get, serving
from support.commands import run_modb_here as modb
from support.gltf_validator import validate

from modb.cli.synth_report import action_line
from modb.database import pgarray
from modb.loader.bvh import read_bvh

SLACK_DEGREES = 10.0  # the issue's: a joint within the examples' range plus this
MET_M = 0.01  # the wrist within this of a reachable target after IK
STILL_M = 0.01  # a planted ankle moves at most this over an action


@pytest.fixture(scope="module")
def dsn(cluster):
    with shared.copy_of_built(cluster, BUILT, build, f"model_actions_{os.getpid()}") as dsn:
        yield dsn


class Rig:
    def __init__(self, dsn: str) -> None:
        with psycopg.connect(dsn) as conn:
            hierarchy, joint_map = conn.execute(
                "SELECT s.hierarchy, s.joint_map FROM modb.graphs g JOIN modb.skeletons s "
                "ON s.id = g.skeleton_id WHERE g.name = %s AND g.kind = 'models'", [GRAPH]
            ).fetchone()  # fmt: skip
        joints = hierarchy["joints"]
        self.names = [j["name"] for j in joints]
        self.parents = [j["parent"] for j in joints]
        self.offsets = np.array([j["offset"] for j in joints])
        self.translated = hierarchy.get("translated", [])
        self.at = {k: self.names.index(v) for k, v in joint_map.items()}

    def fk(self, rotations, translations) -> np.ndarray:
        return own_kinematics.world_positions(self.parents, self.offsets, self.translated,
                                              rotations, translations)  # fmt: skip


def synthesize(dsn, goals, seconds, actions, seed=0):
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        with conn.cursor(binary=True) as cur:
            fps, rotations, translations, report = cur.execute(
                "SELECT fps, rotations, translations, report FROM modb.synthesize_from_models("
                "%s, %s::float8[], %s, %s, 0.5, %s)",
                [GRAPH, goals, seconds, seed, Jsonb(actions)],
            ).fetchone()  # fmt: skip
    return fps, np.asarray(rotations, np.float64), np.asarray(translations, np.float64), report


def model_limits(dsn, action):
    with psycopg.connect(dsn) as conn:
        (data,) = conn.execute(
            "SELECT m.data FROM modb.graphs g JOIN modb.models m "
            "ON m.id = (g.data->'nodes'->%s->>'model_id')::bigint WHERE g.name = %s",
            [action, GRAPH],
        ).fetchone()  # fmt: skip
    return np.asarray(data["limits"]["mean"]), np.asarray(data["limits"]["degrees"])


def angles_from(rotations, mean) -> np.ndarray:
    """Degrees each (..., joints, 4) w-first rotation turns from the mean rotation, by scipy."""
    q = own_kinematics.rotations_of(rotations)
    m = own_kinematics.rotations_of(np.broadcast_to(mean, rotations.shape))
    return np.degrees((m.inv() * q).magnitude()).reshape(rotations.shape[:-1])


def elbow_bend(p, at, side) -> np.ndarray:
    """Degrees the elbow bends (0: straight) from world positions (..., joints, 3)."""
    upper = p[..., at[f"{side}_elbow"], :] - p[..., at[f"{side}_shoulder"], :]
    fore = p[..., at[f"{side}_wrist"], :] - p[..., at[f"{side}_elbow"], :]
    cos = np.sum(upper * fore, -1) / np.linalg.norm(upper, axis=-1) / np.linalg.norm(fore, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def body_jumps(p, at) -> np.ndarray:
    """Per frame step the largest move of a joint relative to the pelvis's ground point."""
    pose = p - (p[:, at["pelvis"]] * np.array([1.0, 0.0, 1.0]))[:, None]
    return np.linalg.norm(np.diff(pose, axis=0), axis=-1).max(axis=1)


@pytest.fixture(scope="module")
def held_out():
    """From the capture: the elbow bends of the right-hand raises the database never saw, and the
    p99.9 of the pose jumps of every right- and left-hand raise (the population the model's
    examples come from, the other hand's mirrored: a mirror image moves as fast)."""
    bends, jumps = [], []
    for action in ("raise_right_hand", "raise_left_hand"):
        unseen, seen = action_files(action)
        for path in unseen + seen:
            m = read_bvh(str(path))
            sk = m.skeleton
            at = {k: sk.index(v) for k, v in sk.joint_map.items()}
            p = own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, m.rotations,
                                               m.translations)  # fmt: skip
            jumps.append(body_jumps(p, at))
            if action == "raise_right_hand" and path in unseen:
                bends.append(elbow_bend(p, at, "right"))
    return np.concatenate(bends), float(np.percentile(np.concatenate(jumps), 99.9))


def test_a_walk_then_a_raise_meets_its_target_feet_planted_pose_natural(dsn, held_out):
    target = [0.3, 1.75, 4.6]
    fps, r, t, report = synthesize(dsn, [[0.0, 3.0]], 14.0,
                                   [{"primitive": "raise_right_hand", "target": target}])
    (done,) = report["actions"]
    assert done["reachable"] and not done["cut"], done
    assert done["ik_error_m"] <= done["placed_error_m"] and done["refined_error_m"] <= (
        done["tree_error_m"] + 1e-9), done  # fmt: skip
    rig = Rig(dsn)
    p = rig.fk(r, t)
    at = rig.at
    key = done["keyframe_frame"]
    assert np.linalg.norm(p[key, at["right_wrist"]] - target) <= MET_M
    # the action's frames: from the frame before it (the seam) to its last
    span = slice(done["first_frame"] - 1, done["first_frame"] + done["n_frames"])
    for side in ("left", "right"):
        ankle = p[span, at[f"{side}_ankle"]][:, [0, 2]]
        assert np.linalg.norm(ankle - ankle[0], axis=-1).max() <= STILL_M, side
    bends, jump_p999 = held_out
    assert body_jumps(p[span], at).max() <= jump_p999
    bend = elbow_bend(p[key], at, "right")
    assert bends.min() - SLACK_DEGREES <= bend <= bends.max() + SLACK_DEGREES
    mean, degrees = model_limits(dsn, "raise_right_hand")
    arm = [at[k] for k in ("right_shoulder", "right_elbow", "right_wrist")]
    turned = angles_from(r[span][:, arm], mean[arm])
    assert (turned <= degrees[arm] + SLACK_DEGREES + 0.5).all(), turned.max(axis=0)
    assert "after IK" in action_line(done)


def test_a_target_out_of_reach_is_said_and_the_nearest_point_kept_natural(dsn):
    target = [0.3, 2.9, 4.6]  # a metre above the hand's highest
    _, r, t, report = synthesize(dsn, [[0.0, 3.0]], 14.0,
                                 [{"primitive": "raise_right_hand", "target": target}])
    (done,) = report["actions"]
    assert done["reachable"] is False and done["unreached_m"] > 0.5, done
    assert any("out of reach" in n for n in report["notes"]), report["notes"]
    rig = Rig(dsn)
    p = rig.fk(r, t)[done["keyframe_frame"]]
    wrist = p[rig.at["right_wrist"]]
    assert abs(np.linalg.norm(wrist - target) - done["unreached_m"]) < 0.002
    assert np.allclose(done["nearest"]["right"], wrist, atol=0.002)
    mean, degrees = model_limits(dsn, "raise_right_hand")
    span = slice(done["first_frame"], done["first_frame"] + done["n_frames"])
    arm = [rig.at[k] for k in ("right_shoulder", "right_elbow")]
    assert (angles_from(r[span][:, arm], mean[arm]) <= degrees[arm] + SLACK_DEGREES + 0.5).all()


def test_goals_and_actions_keep_their_order(dsn):
    goals = [[0.0, 3.0], [-3.0, 6.0]]
    _, _, _, report = synthesize(dsn, goals, 25.0, [
        {"primitive": "raise_left_hand", "target": [-0.3, 1.7, 4.5], "after": 1}])  # fmt: skip
    (done,) = report["actions"]
    reached = {int(k): v for k, v in report["reached"].items()}
    assert reached[1] < done["first_frame"] < reached[3], (reached, done)  # goal, action, goal
    assert report["goals"][0] == goals[0] and report["goals"][2] == goals[1]


def test_a_wave_faces_its_point_for_the_seconds_asked(dsn):
    point = [2.5, 1.5, 5.0]  # ahead and to the left of the walk's end
    fps, r, t, report = synthesize(dsn, [[0.0, 3.0]], 25.0, [
        {"primitive": "wave_right_hand", "target": point, "seconds": 8.0}])  # fmt: skip
    (done,) = report["actions"]
    assert done["n_frames"] >= 8.0 * fps and done["repeats"] >= 1, done
    rig = Rig(dsn)
    span = slice(done["first_frame"], done["first_frame"] + done["n_frames"])
    p = rig.fk(r[span], t[span])
    axis = p[:, rig.at["left_hip"]] - p[:, rig.at["right_hip"]]
    heading = np.arctan2(-axis[:, 2], axis[:, 0])
    pelvis = p[0, rig.at["pelvis"]]
    bearing = np.arctan2(point[0] - pelvis[0], point[2] - pelvis[2])
    off = np.degrees(np.abs(np.angle(np.exp(1j * (heading - bearing)))))
    assert np.median(off) <= 20.0, np.median(off)
    wrist = p[:, rig.at["right_wrist"], 1]
    assert np.percentile(wrist, 75) > p[:, rig.at["right_shoulder"], 1].mean()  # the hand is up


def test_an_action_cut_by_the_strips_end_is_said(dsn):
    _, r, _, report = synthesize(dsn, [[0.0, 3.0]], 3.5, [
        {"primitive": "raise_right_hand", "target": [0.3, 1.75, 4.6]}])  # fmt: skip
    if report["actions"]:
        assert report["actions"][0]["cut"] and any("was cut" in n for n in report["notes"])
    else:  # not even begun: said too
        assert any("not performed" in n for n in report["notes"]), report["notes"]
    assert len(r) == int(round(3.5 * 30)) + 1


@pytest.mark.parametrize("action, words", [
    ({"primitive": "juggle", "target": [0, 1, 2]}, 'no action "juggle" (its actions: '),
    ({"primitive": "raise_right_hand", "target": [0, 1]}, '"target" must be [x, y, z]'),
    ({"primitive": "raise_right_hand"}, 'give a "target"'),
    ({"primitive": "wave_right_hand", "target": [0, 1, 2], "seconds": -1}, '"seconds"'),
    ({"primitive": "raise_right_hand", "target": [0, 1, 2], "after": 3}, '"after"'),
])  # fmt: skip
def test_a_bad_action_is_refused_saying_what_to_give(dsn, action, words):
    with pytest.raises(psycopg.errors.InvalidParameterValue) as e:
        synthesize(dsn, [[0.0, 3.0]], 5.0, [action])
    assert words in str(e.value), str(e.value)


def test_the_command_writes_a_valid_glb_and_reports_each_action(dsn, tmp_path):
    out, report = tmp_path / "raise.glb", tmp_path / "report.json"
    r = modb(dsn, "synth", "--models", GRAPH, "--to", "0,3", "--action",
             "raise_right_hand:0.3,1.75,4.6", "--seconds", "10", "--out", out, "--report",
             "--report-json", report, "-q")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "action raise_right_hand at (0.3, 1.75, 4.6)" in r.stdout and "after IK" in r.stdout
    assert "the place of raise_right_hand (" in r.stdout  # not called a goal
    assert validate(out)["numErrors"] == 0
    steps = json.loads(report.read_text())["steps"]
    assert any(s.get("action") for s in steps)
    r = modb(dsn, "synth", "--to", "0,3", "--action", "raise_right_hand:0,1,2", "--seconds", "5",
             "--out", out)  # fmt: skip
    assert r.returncode == 2 and "--action needs a graph of models" in r.stderr
    r = modb(dsn, "synth", "--models", GRAPH, "--action", "raise_right_hand:0,1", "--seconds",
             "5", "--out", out)  # fmt: skip
    assert r.returncode == 2 and "expected NAME:X,Y,Z" in r.stderr


def test_the_rest_walk_takes_goals_and_actions_in_order_as_the_sql_call(dsn):
    with psycopg.connect(dsn) as conn:
        (ident,) = conn.execute("SELECT id FROM modb.graphs WHERE name = %s", [GRAPH]).fetchone()
    query = "to=0,3&action=raise_right_hand:0.3,1.75,4.6&seconds=10&seed=2"
    with serving(dsn) as address:
        status, walked = get(address, f"/api/graphs/{ident}/synthesis?{query}")
        assert status == 200, walked
        status, body = get(address, f"/api/graphs/{ident}/synthesis?action=raise_right_hand:0,1")
        assert status == 400 and "expected NAME:X,Y,Z" in body["error"], body
        status, body = get(address, f"/api/graphs/{ident}/synthesis?to=0,3&speed=2")
        assert status == 400 and "unknown parameter 'speed'" in body["error"], body
    fps, r, t, report = synthesize(dsn, [[0.0, 3.0]], 10.0, [
        {"primitive": "raise_right_hand", "target": [0.3, 1.75, 4.6], "after": 1}], seed=2)
    assert walked["report"] == report and walked["fps"] == fps
    assert np.allclose(walked["rotations"], r, atol=1e-6)
