"""`modb demo`: real capture into the database, from the shared data or, on a fresh clone, from
PyPI."""

from support.commands import run_modb
from support.data import CMU_UNITS, MOCAP, mocap

from modb.loader.bvh import read_bvh


def test_demo_with_the_shared_data(fresh_db, db, tmp_path):
    mocap("cmu", "131")
    mocap("bandai-2-dev")
    r = run_modb(fresh_db, "demo", "--data", MOCAP, "--cache", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "demo/cmu/131" in r.stdout and "demo/bandai-2/locomotion" in r.stdout
    (clips,) = db.execute("SELECT count(*) FROM modb.current_clips").fetchone()
    assert clips == 1 + 14 + 419  # CMU 01_01, CMU 131, and Bandai dataset 2's walks, turns and runs
    assert "seam roughness" in r.stdout and "goal reach" in r.stdout
    strip = read_bvh(str(tmp_path / "synthesized.bvh"))
    assert (strip.n_frames - 1) / strip.fps >= 60.0 and strip.fps == 30.0


def test_demo_on_a_fresh_clone_downloads_cmu_01_01(fresh_db, db, tmp_path):
    r = run_modb(fresh_db, "demo", "--data", tmp_path / "absent", "--cache", tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    assert "using CMU trial 01_01 from PyPI" in r.stdout
    assert sorted(p.name for p in (tmp_path / "cache" / "cmu-01").iterdir()) == [
        "01.asf",
        "01_01.amc",
    ]
    row = db.execute("SELECT name, n_frames, fps, collection FROM modb.current_clips").fetchone()
    # CMU_data.csv: trial 01_01 runs at 120 fps; the AMC holds 2751 frames.
    assert row == ("01_01", 2751, 120.0, "demo/cmu/01")
    strip = read_bvh(str(tmp_path / "cache" / "synthesized.bvh"), units=CMU_UNITS)
    assert (strip.n_frames - 1) / strip.fps >= 60.0 and strip.fps == 120.0
    assert "goal reach" in r.stdout
