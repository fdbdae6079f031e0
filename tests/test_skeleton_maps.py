"""Joint maps and left/right pairings filled automatically, checked against anatomy and
structure."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import CMU_UNITS, mocap

from modb.loader.bvh import read_bvh
from modb.motion import STANDARD_JOINTS

CASES = {
    # The Bandai skeleton as the data README lists it: 8 sided pairs.
    "bandai": (
        ("bandai-1", "data", "dataset-1_walk_active_001.bvh"),
        "auto",
        {"Shoulder", "UpperArm", "LowerArm", "Hand", "UpperLeg", "LowerLeg", "Foot", "Toes"},
    ),
    # CMU's BVH conversion: 12 pairs, clavicles, hip joints, hands, fingers and thumbs included.
    "cmu-bvh": (
        ("cmu", "131", "bvh", "131_01.bvh"),
        CMU_UNITS,
        {
            "HipJoint",
            "Hip",
            "Knee",
            "Ankle",
            "Toe",
            "Collar",
            "Shoulder",
            "Elbow",
            "Wrist",
            "hand",
            "Fingers",
            "Thumb",
        },
    ),
}
CHAINS = [
    ("pelvis", "spine", "chest", "neck", "head"),
    *[(f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_toe") for s in ("left", "right")],
    *[(f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist") for s in ("left", "right")],
]


def _load(case):
    parts, units, _ = CASES[case]
    return read_bvh(str(mocap(*parts)), units)


def _ancestors(skeleton, k):
    out = []
    while skeleton.joints[k].parent >= 0:
        k = skeleton.joints[k].parent
        out.append(k)
    return out


@pytest.mark.parametrize("case", CASES)
def test_joint_map_is_complete_and_anatomical(case):
    motion = _load(case)
    sk = motion.skeleton
    assert set(sk.joint_map) == set(STANDARD_JOINTS)
    index = {name: sk.index(joint) for name, joint in sk.joint_map.items()}
    for chain in CHAINS:  # each standard joint lies below the previous one in the hierarchy
        for upper, lower in zip(chain, chain[1:]):
            assert index[upper] in _ancestors(sk, index[lower]), (upper, lower)
    # along a limb the joints are consecutive bones (CMU's lhand is not the wrist)
    for chain in CHAINS[1:]:
        for upper, lower in zip(chain, chain[1:]):
            assert sk.joints[index[lower]].parent == index[upper], (upper, lower)
    p = motion.world_positions()
    height = {name: p[:, k, 1].mean() for name, k in index.items()}
    assert height["head"] == max(height.values())
    assert max(height["left_toe"], height["left_ankle"]) < height["left_knee"] < height["pelvis"]
    assert height["left_hip"] < height["left_shoulder"]
    # The pelvis carries the travel (Bandai's top joint joint_Root stands still).
    travel = np.linalg.norm(p[-1, :, [0, 2]] - p[0, :, [0, 2]], axis=0)
    assert travel[index["pelvis"]] > 1.0
    assert travel[index["pelvis"]] >= travel[0] - 1e-9


@pytest.mark.parametrize("case", CASES)
def test_mirror_pairs_cover_every_sided_joint(case):
    motion = _load(case)
    sk = motion.skeleton
    _, _, stems = CASES[case]
    pairs = sk.mirror_pairs
    assert len(pairs) == len(stems)
    paired = {n for pair in pairs for n in pair}
    offsets = {j.name: np.linalg.norm(j.offset) for j in sk.joints}
    parent = {j.name: (sk.joints[j.parent].name if j.parent >= 0 else None) for j in sk.joints}
    partner = {a: b for a, b in pairs} | {b: a for a, b in pairs}
    for left, right in pairs:
        # Captured skeletons are not exactly symmetric (CMU 131 shoulders differ by 1.4 cm).
        assert abs(offsets[left] - offsets[right]) < 0.03, (left, right)
        assert parent[left] == parent[right] or partner.get(parent[left]) == parent[right]
    # Structure alone: an unpaired joint has no sibling-like twin of the same nonzero bone length.
    for j in sk.joints:
        if j.name in paired or offsets[j.name] < 0.01:
            continue
        twins = [
            k.name
            for k in sk.joints
            if k.name != j.name
            and abs(offsets[k.name] - offsets[j.name]) < 0.002
            and parent[k.name] is not None
            and parent[k.name] == parent[j.name]
        ]
        assert not twins, (j.name, twins)
    # Side by position: in the first frame each left joint is on the other side of the body from its
    # partner.
    p = motion.world_positions()[0]
    lr = p[sk.index(sk.joint_map["left_hip"])] - p[sk.index(sk.joint_map["right_hip"])]
    for left, right in pairs:
        if offsets[left] > 0.01:
            assert np.dot(p[sk.index(left)] - p[sk.index(right)], lr) > 0, (left, right)
