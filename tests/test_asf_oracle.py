"""ASF/AMC: world positions of every joint agree with an independent FK, and with CMU's BVH
conversions."""

from __future__ import annotations

import numpy as np
import pytest
from support.asf_oracle import bone_tips, parse_amc, parse_asf
from support.commands import run_modb
from support.data import CMU_UNITS, mocap

from modb.clips import read_motion
from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh

TOLERANCE_M = 0.001
TRIALS = [pytest.param(("131", f"131_{k:02d}"), id=f"131_{k:02d}") for k in range(1, 15)] + [
    pytest.param(("01", "01_01"), id="01_01")
]
# The data README: conversions keep the lower body and the spine up to upperback. The legs are
# compared through both skeletons' automatic joint maps; the spine joints are named per conversion.
LOWER_BODY = ["pelvis"] + [
    f"{s}_{j}" for s in ("left", "right") for j in ("hip", "knee", "ankle", "toe")
]
SPINE = {
    "131": {"lowerback": "lowerback", "Chest": "upperback"},
    "01": {"LowerBack": "lowerback", "Spine": "upperback"},
}


def _asf_path(folder):
    return mocap("cmu", folder, "131.asf" if folder == "131" else "01.asf")


def _compare_to_oracle(motion, asf_path, amc_path):
    """Our joint for bone b sits at b's start, which is the oracle's tip of b's parent."""
    tips, parent = bone_tips(parse_asf(str(asf_path)), parse_amc(str(amc_path)))
    names = motion.skeleton.names
    ours = motion.world_positions()
    worst = 0.0
    for k, name in enumerate(names):
        expected = tips["root"] if name == "root" else tips[parent[name]]
        worst = max(worst, float(np.abs(ours[:, k] - expected).max()))
    return worst


@pytest.mark.parametrize("trial", TRIALS)
def test_parser_matches_independent_forward_kinematics(trial):
    folder, stem = trial
    asf_path, amc_path = _asf_path(folder), mocap("cmu", folder, f"{stem}.amc")
    motion = read_amc(str(amc_path), read_asf(str(asf_path)))
    assert motion.fps == 120.0 and motion.skeleton.unit_m == pytest.approx(CMU_UNITS)
    assert _compare_to_oracle(motion, asf_path, amc_path) < TOLERANCE_M


@pytest.mark.parametrize(
    "trial",
    [("131", "131_01"), ("131", "131_02"), ("131", "131_03"), ("01", "01_01")],
    ids=lambda t: t[1],
)
def test_amc_agrees_with_the_bvh_conversion_on_lower_body_and_spine(trial):
    folder, stem = trial
    amc = read_amc(str(mocap("cmu", folder, f"{stem}.amc")), read_asf(str(_asf_path(folder))))
    bvh_path = (
        mocap("cmu", folder, "bvh", f"{stem}.bvh")
        if folder == "131"
        else mocap("cmu", folder, f"{stem}.bvh")
    )
    bvh = read_bvh(str(bvh_path), CMU_UNITS)
    a, b = amc.world_positions(), bvh.world_positions()
    n = amc.n_frames
    skip = bvh.n_frames - n  # 01_01's conversion has one extra frame at the start (the rest pose)
    assert skip in (0, 1)
    pairs = {bvh.skeleton.joint_map[j]: amc.skeleton.joint_map[j] for j in LOWER_BODY} | SPINE[
        folder
    ]
    assert len(pairs) == 11
    for bvh_name, asf_name in pairs.items():
        pa, pb = a[:, amc.skeleton.index(asf_name)], b[skip:, bvh.skeleton.index(bvh_name)]
        assert np.abs(pa - pb).max() < TOLERANCE_M, (bvh_name, asf_name)


def test_database_path_and_roundtrip(fresh_db, db, tmp_path):
    """Load ASF/AMC, check the stored clip against the oracle, export BVH, load that, compare
    again."""
    folder = mocap("cmu", "131")
    r = run_modb(
        fresh_db, "load", *sorted(folder.glob("*.amc")), "--no-snippets", "--collection", "amc"
    )
    assert r.returncode == 0, r.stderr
    assert "ASF :units length 0.45" in r.stderr and "14 clip versions loaded" in r.stdout
    clips = db.execute("SELECT clip_id, name FROM modb.current_clips ORDER BY name").fetchall()
    worst = 0.0
    for clip_id, name in clips:
        stored = read_motion(db, clip_id)
        worst = max(worst, _compare_to_oracle(stored, folder / "131.asf", folder / f"{name}.amc"))
        r = run_modb(fresh_db, "export", str(clip_id), "--out", tmp_path / f"{name}.bvh")
        assert r.returncode == 0, r.stderr
    r = run_modb(
        fresh_db,
        "load",
        tmp_path,
        "--no-snippets",
        "--collection",
        "reloaded",
        "--units",
        repr(CMU_UNITS),
    )
    assert r.returncode == 0, r.stderr
    for clip_id, name in clips:
        (again_id,) = db.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'reloaded' AND name = %s",
            [name],
        ).fetchone()
        again = read_motion(db, again_id)
        original = read_motion(db, clip_id)
        assert again.skeleton.names == original.skeleton.names
        worst = max(
            worst, float(np.abs(again.world_positions() - original.world_positions()).max())
        )
    assert worst < TOLERANCE_M
