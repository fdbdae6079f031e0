"""World positions of every joint, every frame, every real BVH file agree with bvhio within 1 mm."""

from __future__ import annotations

import os

import numpy as np
import pytest
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import CMU_UNITS, MOCAP, mocap

from modb.loader.bvh import read_bvh

TOLERANCE_M = 0.001
SETS = [("bandai-1", "auto", 0.01), ("cmu/131/bvh", CMU_UNITS, CMU_UNITS)]


def real_files():
    found = []
    for folder, units, unit_m in SETS:
        base = MOCAP / folder
        found += [pytest.param(p, units, unit_m, id=p.name) for p in sorted(base.rglob("*.bvh"))]
    return found


FILES = real_files()
if not FILES:
    pytest.skip(f"real BVH data not found under {MOCAP} (set MODB_MOCAP)", allow_module_level=True)


@pytest.mark.parametrize("path,units,unit_m", FILES)
def test_parser_forward_kinematics_matches_bvhio(path, units, unit_m):
    motion = read_bvh(str(path), units)
    assert motion.skeleton.unit_m == pytest.approx(unit_m)
    names, expected = bvhio_world_positions(str(path), unit_m)
    ours = in_order(motion.skeleton.names, names, motion.world_positions())
    assert ours.shape == expected.shape
    assert np.abs(ours - expected).max() < TOLERANCE_M


def test_database_forward_kinematics_matches_bvhio(fresh_db, db):
    """Through the database: stored as real[], FK by the server's PL/Python (numpy 1.24)."""
    for folder, units, _ in SETS:
        r = run_modb(
            fresh_db,
            "load",
            mocap(folder),
            "--no-snippets",
            "--units",
            units if isinstance(units, str) else repr(units),
        )
        assert r.returncode == 0, r.stderr
    # Bandai keeps each file's start position in the Hips offset; its position channels replace it,
    # so dataset 1 needs two skeletons (the 11 "normal" files have a 10 cm Head End Site), CMU 131
    # one.
    assert db.execute("SELECT count(*) FROM modb.skeletons").fetchone()[0] == 3
    clips = db.execute(
        "SELECT clip_id, source_file FROM modb.current_clips ORDER BY clip_id"
    ).fetchall()
    assert len(clips) == len(FILES)
    unit_of = {os.path.abspath(p.values[0]): p.values[2] for p in FILES}
    worst = 0.0
    for clip_id, source_file in clips:
        names, expected = bvhio_world_positions(source_file, unit_of[source_file])
        rows = db.execute(
            "SELECT frame, joint, x, y, z FROM modb.world_positions(%s) ORDER BY frame, "
            "joint_index",
            [clip_id],
        ).fetchall()
        n_joints = len(names)
        joint_names = [r[1] for r in rows[:n_joints]]
        positions = np.array([r[2:] for r in rows]).reshape(-1, n_joints, 3)
        ours = in_order(joint_names, names, positions)
        assert ours.shape == expected.shape, source_file
        worst = max(worst, float(np.abs(ours - expected).max()))
    assert worst < TOLERANCE_M
