"""Posture and pace of a source (modb.posture, issue 41), on real files and without a database: the
elbow bend and upper-arm angle checked against this test's own forward kinematics (scipy), kept by
retargeting CMU 16 onto the Bandai rig, and the fact the mixed-pool note rests on: Bandai's active
walks bend the elbows where CMU 16's ordinary walks never do, its exhausted walks overlap them."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import mocap
from support.snippet_oracle import motion_world

from modb.editing.retarget import retarget_motion
from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.posture import PERCENTILES, apart, posture


@pytest.fixture(scope="module")
def cmu_walks():
    asf = read_asf(str(mocap("cmu", "16", "16.asf")))
    return [read_amc(str(mocap("cmu", "16", f"16_{n}.amc")), asf) for n in ("15", "21", "34")]


def bandai(style: str, count: int = 4):
    files = sorted(mocap("bandai-2-dev", "data").glob(f"dataset-2_walk_{style}_*.bvh"))[:count]
    return [read_bvh(str(f)) for f in files]


def oracle_elbow_bend(motions) -> np.ndarray:
    bends = []
    for m in motions:
        positions, _ = motion_world(m)
        sk = m.skeleton
        for side in ("left", "right"):
            s, e, w = (
                positions[:, sk.index(sk.joint_map[f"{side}_{j}"])]
                for j in ("shoulder", "elbow", "wrist")
            )
            upper, lower = e - s, w - e
            cos = (
                np.einsum("fi,fi->f", upper, lower)
                / np.linalg.norm(upper, axis=1)
                / np.linalg.norm(lower, axis=1)
            )
            bends.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return np.percentile(np.concatenate(bends), PERCENTILES)


def test_elbow_bend_is_the_angle_between_the_arm_bones(cmu_walks):
    for motions in (cmu_walks, bandai("active")):
        measured = posture(motions)[0]
        assert measured.name == "elbow bend"
        np.testing.assert_allclose(measured.percentiles, oracle_elbow_bend(motions), atol=1e-6)


def test_retargeting_keeps_the_posture(cmu_walks):
    reference = bandai("active", 1)[0]
    moved = [retarget_motion(m, reference.skeleton, 30, reference) for m in cmu_walks]
    before, after = posture(cmu_walks), posture(moved)
    for a, b in zip(before[:2], after[:2], strict=True):  # angles; the pace scales with the legs
        np.testing.assert_allclose(a.percentiles, b.percentiles, atol=1.5, err_msg=a.name)


def test_power_walks_and_ordinary_walks_are_apart_where_tired_walks_are_not(cmu_walks):
    ordinary = posture(cmu_walks)
    assert "elbow bend" in apart(ordinary, posture(bandai("active")))
    assert "elbow bend" not in apart(ordinary, posture(bandai("exhausted")))
