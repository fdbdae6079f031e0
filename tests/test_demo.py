"""`modb demo`: real capture into the database, from the shared data or, on a fresh clone, from PyPI."""
from conftest import MOCAP, mocap, run_modb


def test_demo_with_the_shared_data(fresh_db, db):
    mocap("cmu", "131")
    r = run_modb(fresh_db, "demo", "--data", MOCAP)
    assert r.returncode == 0, r.stderr
    assert "demo/cmu/131" in r.stdout and "demo/bandai-1" in r.stdout
    (clips,) = db.execute("SELECT count(*) FROM modb.current_clips").fetchone()
    assert clips == 1 + 14 + 174


def test_demo_on_a_fresh_clone_downloads_cmu_01_01(fresh_db, db, tmp_path):
    r = run_modb(fresh_db, "demo", "--data", tmp_path / "absent", "--cache", tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    assert "using CMU trial 01_01 from PyPI" in r.stdout
    assert sorted(p.name for p in (tmp_path / "cache" / "cmu-01").iterdir()) == ["01.asf", "01_01.amc"]
    row = db.execute("SELECT name, n_frames, fps, collection FROM modb.current_clips").fetchone()
    # CMU_data.csv: trial 01_01 runs at 120 fps; the AMC holds 2751 frames.
    assert row == ("01_01", 2751, 120.0, "demo/cmu/01")
