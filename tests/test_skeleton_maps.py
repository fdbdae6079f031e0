"""Joint maps and left/right pairings filled automatically, checked against anatomy and
structure."""

from __future__ import annotations

import numpy as np
import pytest
from support.data import CMU_UNITS, mocap
from support.commands import run_modb

from modb.loader.bvh import read_bvh
from modb.loader.skeleton_maps import explain_joint_map, guess_joint_map
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


# Rigs of the common naming families, written here joint by joint: (name, parent, offset in cm;
# +x is the figure's left, +y up, it faces +z). The maps expected are anatomy's: the joint each
# standard name sits at, or the nearest joint of its chain standing in where the rig has none.
def _sided(parent_l, parent_r, spec):
    """spec: (left name, right name, parent of the first, offset of the left side) per joint; the
    right side mirrors x."""
    out = []
    for left, right, parent, (x, y, z) in spec:
        out.append((left, parent_l if parent is None else parent[0], (x, y, z)))
        out.append((right, parent_r if parent is None else parent[1], (-x, y, z)))
    return out


def _limbs(prefix, hip_parent, arm_parent, leg, arm, left=("Left", "Right")):
    """Legs and arms named prefix + side + stem (stems: the leg's and arm's joints, top first)."""
    rig = []
    for stems, parent, offsets in (
        (leg, hip_parent, [(9, -6, 0), (0, -42, 0), (0, -40, 0), (0, -6, 12)]),
        (arm, arm_parent, [(3, 4, 0), (12, 0, 0), (28, 0, 0), (25, 0, 0)]),
    ):
        for side, sign in zip(left, (1, -1)):
            above = parent
            for stem, (x, y, z) in zip(
                stems, offsets[-len(stems) :] if len(stems) < 4 else offsets
            ):
                name = f"{prefix}{side}{stem}" if side else f"{prefix}{stem}"
                rig.append((name, above, (sign * x, y, z)))
                above = name
    return rig


def _trunk(chain, up=12.0):
    """chain: (name, parent) from the root up; the root at 95 cm, each next joint `up` above."""
    return [(n, p, (0, 95 if p is None else up, 0)) for n, p in chain]


MIXAMO = [
    *_trunk(
        [
            ("mixamorig:Hips", None),
            ("mixamorig:Spine", "mixamorig:Hips"),
            ("mixamorig:Spine1", "mixamorig:Spine"),
            ("mixamorig:Spine2", "mixamorig:Spine1"),
            ("mixamorig:Neck", "mixamorig:Spine2"),
            ("mixamorig:Head", "mixamorig:Neck"),
        ]
    ),
    *_limbs(
        "mixamorig:",
        "mixamorig:Hips",
        "mixamorig:Spine2",
        ["UpLeg", "Leg", "Foot", "ToeBase"],
        ["Shoulder", "Arm", "ForeArm", "Hand"],
    ),
]
CMU31 = [
    *_trunk(
        [
            ("Hips", None),
            ("LowerBack", "Hips"),
            ("Spine", "LowerBack"),
            ("Spine1", "Spine"),
            ("Neck", "Spine1"),
            ("Neck1", "Neck"),
            ("Head", "Neck1"),
        ],
        up=9.0,
    ),
    ("LHipJoint", "Hips", (5, -3, 0)),
    ("RHipJoint", "Hips", (-5, -3, 0)),
    *_sided(
        "LHipJoint",
        "RHipJoint",
        [
            ("LeftUpLeg", "RightUpLeg", None, (4, -3, 0)),
            ("LeftLeg", "RightLeg", ("LeftUpLeg", "RightUpLeg"), (0, -42, 0)),
            ("LeftFoot", "RightFoot", ("LeftLeg", "RightLeg"), (0, -40, 0)),
            ("LeftToeBase", "RightToeBase", ("LeftFoot", "RightFoot"), (0, -6, 12)),
        ],
    ),
    *_limbs("", "Hips", "Spine1", [], ["Shoulder", "Arm", "ForeArm", "Hand"]),
]
MINIMAL = [
    *_trunk([("Hips", None), ("Spine", "Hips"), ("Head", "Spine")], up=30.0),
    *_limbs(
        "",
        "Hips",
        "Spine",
        ["UpLeg", "Leg", "Foot", "ToeBase"],
        ["Shoulder", "Arm", "ForeArm", "Hand"],
    ),
]
# feet without toes: the ankle stands in for the toe
NO_TOES = [
    *_trunk([("Hips", None), ("Spine", "Hips"), ("Head", "Spine")], up=30.0),
    *_limbs("", "Hips", "Spine", ["UpLeg", "Leg", "Foot"], ["Shoulder", "Arm", "ForeArm", "Hand"]),
]
CUSTOM = [
    *_trunk(
        [
            ("RootJoint", None),
            ("pelvis_lowerback", "RootJoint"),
            ("lowerback_torso", "pelvis_lowerback"),
            ("torso_head", "lowerback_torso"),
        ],
        up=20.0,
    ),
    *_limbs(
        "",
        "RootJoint",
        "lowerback_torso",
        ["Hip", "Knee", "Ankle", "ToeJoint"],
        ["Shoulder", "Elbow", "Wrist"],
        left=("l", "r"),
    ),
]
BLENDER = [
    *_trunk(
        [
            ("pelvis", None),
            ("spine", "pelvis"),
            ("spine.001", "spine"),
            ("chest", "spine.001"),
            ("neck", "chest"),
            ("head", "neck"),
        ]
    ),
    *[
        (name.replace("+", side), parent and parent.replace("+", side), (sign * x, y, z))
        for side, sign in ((".L", 1), (".R", -1))
        for name, parent, (x, y, z) in [
            ("thigh+", "pelvis", (9, -6, 0)),
            ("shin+", "thigh+", (0, -42, 0)),
            ("foot+", "shin+", (0, -40, 0)),
            ("toe+", "foot+", (0, -6, 12)),
            ("shoulder+", "chest", (3, 4, 0)),
            ("upper_arm+", "shoulder+", (12, 0, 0)),
            ("forearm+", "upper_arm+", (28, 0, 0)),
            ("hand+", "forearm+", (25, 0, 0)),
        ]
    ],
]
UNITY = [
    *_trunk(
        [
            ("Hips", None),
            ("Spine", "Hips"),
            ("Chest", "Spine"),
            ("UpperChest", "Chest"),
            ("Neck", "UpperChest"),
            ("Head", "Neck"),
        ]
    ),
    *_limbs(
        "",
        "Hips",
        "UpperChest",
        ["UpperLeg", "LowerLeg", "Foot", "Toes"],
        ["Shoulder", "UpperArm", "LowerArm", "Hand"],
    ),
]


def _limb_map(leg, arm, name=lambda side, stem: side + stem, sides=("Left", "Right")):
    out = {}
    for standard_side, side in zip(("left", "right"), sides):
        for standard, stem in zip(("hip", "knee", "ankle", "toe"), leg):
            out[f"{standard_side}_{standard}"] = name(side, stem)
        for standard, stem in zip(("shoulder", "elbow", "wrist"), arm):
            out[f"{standard_side}_{standard}"] = name(side, stem)
    return out


def _trunk_map(pelvis, spine, chest, neck, head):
    return dict(
        zip(("pelvis", "spine", "chest", "neck", "head"), (pelvis, spine, chest, neck, head))
    )


# family: (rig, the map anatomy expects, the standard joints the hierarchy gives (names miss them))
RIGS = {
    "mixamo": (
        MIXAMO,
        {
            k: "mixamorig:" + v
            for k, v in (
                _trunk_map("Hips", "Spine", "Spine2", "Neck", "Head")
                | _limb_map(["UpLeg", "Leg", "Foot", "ToeBase"], ["Arm", "ForeArm", "Hand"])
            ).items()
        },
        set(),
    ),
    "cmu-31": (
        CMU31,
        _trunk_map("Hips", "Spine", "Spine1", "Neck", "Head")
        | _limb_map(["UpLeg", "Leg", "Foot", "ToeBase"], ["Arm", "ForeArm", "Hand"]),
        {"chest"},
    ),
    # no chest, no neck: the spine stands in for both, where the arms and the head branch
    "minimal": (
        MINIMAL,
        _trunk_map("Hips", "Spine", "Spine", "Spine", "Head")
        | _limb_map(["UpLeg", "Leg", "Foot", "ToeBase"], ["Arm", "ForeArm", "Hand"]),
        {"chest", "neck"},
    ),
    "no-toes": (
        NO_TOES,
        _trunk_map("Hips", "Spine", "Spine", "Spine", "Head")
        | _limb_map(["UpLeg", "Leg", "Foot", "Foot"], ["Arm", "ForeArm", "Hand"]),
        {"chest", "neck", "left_toe", "right_toe"},
    ),
    "custom": (
        CUSTOM,
        _trunk_map(
            "RootJoint", "pelvis_lowerback", "lowerback_torso", "lowerback_torso", "torso_head"
        )
        | _limb_map(
            ["Hip", "Knee", "Ankle", "ToeJoint"], ["Shoulder", "Elbow", "Wrist"], sides=("l", "r")
        ),
        {"pelvis", "spine", "chest", "neck", "head"},
    ),
    "blender": (
        BLENDER,
        _trunk_map("pelvis", "spine", "chest", "neck", "head")
        | _limb_map(
            ["thigh", "shin", "foot", "toe"],
            ["upper_arm", "forearm", "hand"],
            name=lambda side, stem: stem + side,
            sides=(".L", ".R"),
        ),
        set(),
    ),
    "unity": (
        UNITY,
        _trunk_map("Hips", "Spine", "Chest", "Neck", "Head")
        | _limb_map(["UpperLeg", "LowerLeg", "Foot", "Toes"], ["UpperArm", "LowerArm", "Hand"]),
        set(),
    ),
}


def _write_bvh(path, rig, frames=48, fps=30.0):
    """A BVH of the rig walking: 1.2 m/s forward, legs and arms swinging at 1 Hz."""
    children = {}
    for name, parent, _ in rig:
        children.setdefault(parent, []).append(name)
    offset = {name: o for name, _, o in rig}
    lines, order = ["HIERARCHY"], []

    def joint(name, depth):
        pad = "  " * depth
        root = depth == 0
        lines.append(f"{pad}{'ROOT' if root else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(pad + "  OFFSET " + " ".join(f"{v:g}" for v in offset[name]))
        channels = "Xposition Yposition Zposition " if root else ""
        lines.append(f"{pad}  CHANNELS {6 if root else 3} {channels}Zrotation Xrotation Yrotation")
        order.append(name)
        for child in children.get(name, []):
            joint(child, depth + 1)
        if name not in children:
            lines.append(pad + "  End Site")
            lines.append(pad + "  {")
            lines.append(
                pad + ("    OFFSET 0 0 5" if "toe" in name.lower() else "    OFFSET 0 -5 0")
            )
            lines.append(pad + "  }")
        lines.append(pad + "}")

    joint(children[None][0], 0)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {1 / fps:.6f}"]
    swing = {}  # joint -> (amplitude in degrees, phase): thighs and upper arms opposite
    for name, parent, _ in rig:
        low = name.lower().split(":")[-1]
        left = low.startswith(("left", "l")) and not low.startswith("lowerback") or ".l" in low
        phase = 0.0 if left else np.pi
        if any(w in low for w in ("upleg", "upperleg", "thigh", "hip")) and "hipjoint" not in low:
            swing[name] = (30.0, phase)
        elif any(w in low for w in ("knee", "shin", "lowerleg")) or low.endswith("leg"):
            swing[name] = (-20.0, phase + 1.0)
        elif low.endswith("arm") and not any(w in low for w in ("fore", "lower")):
            swing[name] = (-20.0, phase)
    for f in range(frames):
        t = f / fps
        values = []
        for name in order:
            if name == order[0]:
                values += [0.0, 95.0 + 2 * np.cos(4 * np.pi * t), 120.0 * t]
            amplitude, phase = swing.get(name, (0.0, 0.0))
            x = amplitude * np.sin(2 * np.pi * t + phase)
            if amplitude < 0:
                x = -amplitude * (1 + np.sin(2 * np.pi * t + phase)) / 2
            values += [0.0, x, 0.0]
        lines.append(" ".join(f"{v:.4f}" for v in values))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("family", RIGS)
def test_joint_map_of_each_naming_family(family, tmp_path):
    rig, expected, from_hierarchy = RIGS[family]
    motion = read_bvh(str(_write_bvh(tmp_path / f"{family}.bvh", rig)), "cm")
    assert motion.skeleton.joint_map == expected
    names, parents = motion.skeleton.names, motion.skeleton.parents
    joint_map, filled = explain_joint_map(names, parents)
    assert joint_map == expected and set(filled) == from_hierarchy
    # parents may be given by name too
    by_name = [names[p] if p >= 0 else None for p in parents]
    assert guess_joint_map(names, by_name) == expected


@pytest.mark.parametrize("family", RIGS)
def test_each_naming_family_loads_with_snippets(family, fresh_db, db, tmp_path):
    rig, expected, from_hierarchy = RIGS[family]
    path = _write_bvh(tmp_path / f"{family}.bvh", rig)
    r = run_modb(fresh_db, "load", path, "--units", "cm")
    assert r.returncode == 0, r.stderr
    notes = [line for line in r.stderr.splitlines() if "joint map from the hierarchy" in line]
    if from_hierarchy:
        assert len(notes) == 1, r.stderr
        for standard in from_hierarchy:
            assert f" {standard} " in notes[0] or f"no {standard} joint" in notes[0], notes
    else:
        assert not notes, r.stderr
    (stored,) = db.execute("SELECT joint_map FROM modb.skeletons").fetchone()
    assert stored == expected
    (snippets,) = db.execute("SELECT count(*) FROM modb.snippets").fetchone()
    assert snippets > 0
    r = run_modb(fresh_db, "list", "--skeletons")
    assert r.returncode == 0, r.stderr
    shown = r.stdout.splitlines()
    assert shown[0].split()[1:] == [family, "(1", "clip", "versions)"]
    assert shown[1].strip() == ", ".join(f"{s}: {expected[s]}" for s in STANDARD_JOINTS)
