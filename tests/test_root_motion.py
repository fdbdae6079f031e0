"""Root motion on synthesized strips (issue 24): the travel on the top joint, smooth across seams,
on the ground, not following the sway within a step, every other joint where it was. Checked with
scipy's kinematics (snippet_oracle), on Bandai's rig (a still `joint_Root` above `Hips`) and CMU's
(the pelvis is the top joint: a `root_motion` joint is added)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.commands import run_modb
from support.bvh_oracle import bvhio_world_positions
from support.snippet_oracle import motion_world

from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.root_motion import with_root_motion
from modb.synthesis.synth import source_motions, synthesize

COURSE = [(0.0, 5.0), (5.0, 5.0), (5.0, 0.0)]


def yaw(orientations: list[Rotation], joint: int) -> np.ndarray:
    """The top joint's heading about +Y (0 facing +Z), unwrapped, from its world orientation."""
    forward = orientations[joint].apply([0.0, 0.0, 1.0])
    return np.unwrap(np.arctan2(forward[:, 0], forward[:, 2]))


def pelvis_limits(conn, first_snippet: int, collection) -> tuple[float, float]:
    """The source clips' own pelvis: p99.9 of its ground step and of its heading change per frame
    (the hip axis's, as the database measures heading), from scipy's kinematics."""
    steps, turns = [], []
    for m in source_motions(conn, first_snippet, collection):
        sk = m.skeleton
        positions, _ = motion_world(m)
        pelvis = positions[:, sk.index(sk.joint_map["pelvis"])] * [1, 0, 1]
        steps.append(np.linalg.norm(np.diff(pelvis, axis=0), axis=1))
        axis = (
            positions[:, sk.index(sk.joint_map["left_hip"])]
            - positions[:, sk.index(sk.joint_map["right_hip"])]
        )
        turns.append(np.abs(np.diff(np.unwrap(np.arctan2(-axis[:, 2], axis[:, 0])))))
    return float(np.percentile(np.concatenate(steps), 99.9)), float(
        np.percentile(np.concatenate(turns), 99.9)
    )


def check_root_motion(conn, result, collection) -> None:
    strip = result.strip
    moved = with_root_motion(strip)
    sk, new = strip.skeleton, moved.skeleton
    added = len(new.joints) - len(sk.joints)
    before, _ = motion_world(strip)
    after, orientations = motion_world(moved)
    # every joint of the source skeleton where it was (the top one too when a joint was added)
    kept = slice(0 if added else 1, None)
    assert np.abs(after[:, added:][:, kept] - before[:, kept]).max() < 1e-9
    root = after[:, 0]
    assert np.abs(root[:, 1]).max() < 1e-12  # on the ground
    step_limit, turn_limit = pelvis_limits(conn, result.chain[0].snippet_id, collection)
    steps = np.linalg.norm(np.diff(root, axis=0), axis=1)
    turns = np.abs(np.diff(yaw(orientations, 0)))
    assert steps.max() <= step_limit, (steps.max(), step_limit)
    assert turns.max() <= turn_limit, (turns.max(), turn_limit)
    # no jump at a seam: the largest step there is no more than the largest elsewhere
    seams = np.array([c.start_frame for c in result.chain[1:]])
    assert steps[seams - 1].max() <= steps.max()
    # the sway within a step is left to the pelvis: the top joint's ground acceleration (the sway
    # swings the pelvis side to side at the stride's rate) is a small part of the pelvis's
    pelvis = before[:, sk.index(sk.joint_map["pelvis"])] * [1, 0, 1]

    def acceleration(path):
        return np.sqrt((np.diff(path, 2, axis=0) ** 2).sum(axis=1).mean()) * strip.fps**2

    assert acceleration(root) < 0.25 * acceleration(pelvis), (
        acceleration(root),
        acceleration(pelvis),
    )


def test_root_motion_on_bandai_keeps_its_top_joint_and_every_joint_in_place(locomotion):
    with connect(locomotion) as conn:
        result = synthesize(conn, COURSE, 30.0, Settings())
        assert result.strip.skeleton.names[0] == "joint_Root"
        assert with_root_motion(result.strip).skeleton.names == result.strip.skeleton.names
        check_root_motion(conn, result, result.collection)


def test_root_motion_on_cmu_adds_a_top_joint_above_the_pelvis(cmu):
    with connect(cmu) as conn:
        result = synthesize(conn, COURSE, 20.0, Settings(graph="none", collection="cmu/131"))
        moved = with_root_motion(result.strip)
        assert moved.skeleton.names == ["root_motion", *result.strip.skeleton.names]
        check_root_motion(conn, result, "cmu/131")


@pytest.mark.parametrize("in_place", [False, True])
def test_synth_writes_root_motion_unless_asked_in_place(locomotion, tmp_path, in_place):
    out = tmp_path / "walk.bvh"
    args = ["--to", "0,5", "--to", "5,5", "--seconds", "15", "--out", out, "-q"]
    r = run_modb(locomotion, "synth", *args, *(["--in-place"] if in_place else []))
    assert r.returncode == 0, r.stderr
    with connect(locomotion) as conn:
        result = synthesize(conn, [(0.0, 5.0), (5.0, 5.0)], 15.0, Settings())
    names, positions = bvhio_world_positions(str(out), result.strip.skeleton.unit_m)
    top = positions[:, names.index("joint_Root")]
    steps = np.linalg.norm(np.diff(top, axis=0), axis=1)
    if in_place:  # the source's own top joint, as placed: it jumps at seams
        assert steps.max() > 0.5
    else:
        assert steps.max() < 0.05 and np.abs(top[:, 1]).max() < 1e-6
