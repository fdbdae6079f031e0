"""Load -> export -> load reproduces every joint position within 1 mm, read back by us and by
bvhio."""

from __future__ import annotations

import numpy as np
import pytest
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import CMU_UNITS, mocap

from modb.bvh_export import write_bvh
from modb.clips import read_motion
from modb.loader.bvh import read_bvh

TOLERANCE_M = 0.001


@pytest.mark.parametrize("folder,units", [("bandai-1", "auto"), ("cmu/131/bvh", repr(CMU_UNITS))])
def test_load_export_load_roundtrip(fresh_db, db, tmp_path, folder, units):
    source = mocap(folder)
    r = run_modb(
        fresh_db, "load", source, "--no-snippets", "--collection", "original", "--units", units
    )
    assert r.returncode == 0, r.stderr
    clips = db.execute(
        "SELECT clip_id, name, source_file FROM modb.current_clips ORDER BY clip_id"
    ).fetchall()
    out_dir = tmp_path / "exported"
    out_dir.mkdir()
    for k, (clip_id, name, _) in enumerate(clips):
        out = out_dir / f"{name}.bvh"
        if k < 2:  # the command line itself, for a couple of clips
            r = run_modb(fresh_db, "export", str(clip_id), "--out", out)
            assert r.returncode == 0, r.stderr
        else:
            with open(out, "w") as f:
                write_bvh(read_motion(db, clip_id), f)
    r = run_modb(
        fresh_db, "load", out_dir, "--no-snippets", "--collection", "reloaded", "--units", units
    )
    assert r.returncode == 0, r.stderr
    assert f"{len(clips)} clip versions loaded" in r.stdout

    unit_m = 0.01 if units == "auto" else CMU_UNITS
    worst = {"bvhio": 0.0, "modb": 0.0, "reloaded": 0.0}
    for clip_id, name, source_file in clips:
        names, original = bvhio_world_positions(source_file, unit_m)
        exported = out_dir / f"{name}.bvh"
        names2, exported_bvhio = bvhio_world_positions(str(exported), unit_m)
        assert names2 == names
        worst["bvhio"] = max(worst["bvhio"], np.abs(exported_bvhio - original).max())
        reread = read_bvh(str(exported), units if units == "auto" else float(units))
        worst["modb"] = max(
            worst["modb"],
            np.abs(
                in_order(reread.skeleton.names, names, reread.world_positions()) - original
            ).max(),
        )
        (reloaded_id,) = db.execute("SELECT modb.find_collection('reloaded')").fetchone()
        (clip2,) = db.execute(
            "SELECT id FROM modb.clips WHERE collection_id = %s AND name = %s", [reloaded_id, name]
        ).fetchone()
        again = read_motion(db, clip2)
        first = read_motion(db, clip_id)
        # offsets and End Sites survive
        for j1, j2 in zip(first.skeleton.joints, again.skeleton.joints):
            assert j1.name == j2.name and np.allclose(j1.offset, j2.offset, atol=1e-6)
            assert (j1.end_site is None) == (j2.end_site is None)
            assert j1.end_site is None or np.allclose(j1.end_site, j2.end_site, atol=1e-6)
        worst["reloaded"] = max(
            worst["reloaded"],
            np.abs(in_order(again.skeleton.names, names, again.world_positions()) - original).max(),
        )
    assert max(worst.values()) < TOLERANCE_M, worst


def test_export_of_an_older_version_and_ambiguous_names(fresh_db, db, tmp_path):
    src = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    for collection in ("a", "b"):
        assert run_modb(fresh_db, "load", src, "--collection", collection).returncode == 0
    r = run_modb(fresh_db, "export", "dataset-1_walk_active_001", "--out", tmp_path / "x.bvh")
    assert (
        r.returncode == 1
        and "2 clips are named" in r.stderr
        and "a/dataset-1_walk_active_001" in r.stderr
    )
    assert not (tmp_path / "x.bvh").exists()
    # A changed file adds version 2; --version 1 still exports the original motion.
    changed = tmp_path / "dataset-1_walk_active_001.bvh"
    text = src.read_text().splitlines()
    motion_at = text.index("MOTION")
    text[motion_at + 3] = " ".join("0" for _ in text[motion_at + 3].split())  # first frame zeroed
    changed.write_text("\n".join(text) + "\n")
    r = run_modb(fresh_db, "load", changed, "--collection", "a")
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout, r.stdout + r.stderr
    for version, reference in ((1, src), (2, changed)):
        out = tmp_path / f"v{version}.bvh"
        r = run_modb(
            fresh_db, "export", "a/dataset-1_walk_active_001", "--version", version, "--out", out
        )
        assert r.returncode == 0, r.stderr
        names, expected = bvhio_world_positions(str(reference), 0.01)
        names2, got = bvhio_world_positions(str(out), 0.01)
        assert np.abs(got - expected).max() < TOLERANCE_M
    r = run_modb(fresh_db, "export", "a/dataset-1_walk_active_001", "--version", "7", process=True)
    assert r.returncode == 1 and "has no version 7" in r.stderr  # (a subprocess smoke test)


def test_a_numeric_name_is_not_taken_for_an_id(fresh_db, db, tmp_path):
    walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    named = tmp_path / "1.bvh"
    named.write_bytes(mocap("bandai-1", "data", "dataset-1_run_active_001.bvh").read_bytes())
    assert run_modb(fresh_db, "load", walk, named, "--collection", "c").returncode == 0
    (walk_id,) = db.execute(
        "SELECT clip_id FROM modb.current_clips WHERE name = 'dataset-1_walk_active_001'"
    ).fetchone()
    assert walk_id == 1
    r = run_modb(fresh_db, "export", "1")
    assert r.returncode == 1 and "both a clip id and a clip name" in r.stderr
    by_id = run_modb(fresh_db, "export", "id:1")
    by_name = run_modb(fresh_db, "export", "c/1")
    assert by_id.returncode == by_name.returncode == 0
    assert "Frames: 146" in by_id.stdout and by_name.stdout != by_id.stdout
    r = run_modb(fresh_db, "export", "id:1", "--out", tmp_path / "missing" / "x.bvh")
    assert r.returncode == 1 and "cannot write" in r.stderr
