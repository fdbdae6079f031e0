"""Load -> export -> load reproduces every joint position within 1 mm, read back by us and by
bvhio: CMU 131's BVH trials, and files of Bandai dataset 1 covering each of its motions and each of
its styles (20 of its 174 files, both of its skeletons). bvhio takes about a second a thousand
frames, twice a file: over all of dataset 1, most of this module's time (test_bvh_oracle compares
every file as read with bvhio)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import CMU_UNITS, mocap

from modb.bvh_export import write_bvh
from modb.clips import read_motion
from modb.loader.bvh import read_bvh

TOLERANCE_M = 0.001


def bandai_sample(folder: Path) -> Path:
    """A folder of links to files of Bandai dataset 1 covering each of its motions and each of its
    styles: the k-th motion's k-th file (the styles taken in turn), then for each style not yet
    chosen its walk (the first take)."""
    by_motion: dict[str, list[Path]] = {}
    for f in sorted(mocap("bandai-1", "data").glob("*.bvh")):  # dataset-1_MOTION_STYLE_NNN.bvh
        by_motion.setdefault(f.name.split("_")[1], []).append(f)
    chosen = [files[k % len(files)] for k, files in enumerate(by_motion.values())]
    styles = {f.name.split("_")[2] for f in chosen}
    for f in by_motion["walk"]:
        if f.name.split("_")[2] not in styles:
            chosen.append(f)
            styles.add(f.name.split("_")[2])
    folder.mkdir()
    for f in chosen:
        (folder / f.name).symlink_to(f)
    return folder


@pytest.mark.parametrize("folder,units", [("bandai-1", "auto"), ("cmu/131/bvh", repr(CMU_UNITS))])
def test_load_export_load_roundtrip(fresh_db, db, tmp_path, folder, units):
    source = bandai_sample(tmp_path / "bandai-1") if folder == "bandai-1" else mocap(folder)
    r = run_modb(fresh_db, "load", source, "--no-snippets", "--collection", "original",
                 "--units", units, process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    clips = db.execute(
        "SELECT clip_id, name, source_file FROM modb.current_clips ORDER BY clip_id"
    ).fetchall()
    out_dir = tmp_path / "exported"
    out_dir.mkdir()
    for k, (clip_id, name, _) in enumerate(clips):
        out = out_dir / f"{name}.bvh"
        if k < 2:  # the command line itself, for a couple of clips
            r = run_modb(fresh_db, "export", str(clip_id), "--out", out, process=False)
            assert r.returncode == 0, r.stderr
        else:
            with open(out, "w") as f:
                write_bvh(read_motion(db, clip_id), f)
    r = run_modb(fresh_db, "load", out_dir, "--no-snippets", "--collection", "reloaded",
                 "--units", units, process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"{len(clips)} clip versions loaded" in r.stdout
    (reloaded_id,) = db.execute("SELECT modb.find_collection('reloaded')").fetchone()

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
        r = run_modb(fresh_db, "load", src, "--collection", collection, process=False)
        assert r.returncode == 0, r.stderr
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
    r = run_modb(fresh_db, "load", changed, "--collection", "a", process=False)
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout, r.stdout + r.stderr
    for version, reference in ((1, src), (2, changed)):
        out = tmp_path / f"v{version}.bvh"
        r = run_modb(fresh_db, "export", "a/dataset-1_walk_active_001", "--version", version,
                     "--out", out, process=False)  # fmt: skip
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
    r = run_modb(fresh_db, "load", walk, named, "--collection", "c", process=False)
    assert r.returncode == 0, r.stderr
    (walk_id,) = db.execute(
        "SELECT clip_id FROM modb.current_clips WHERE name = 'dataset-1_walk_active_001'"
    ).fetchone()
    assert walk_id == 1
    r = run_modb(fresh_db, "export", "1")
    assert r.returncode == 1 and "both a clip id and a clip name" in r.stderr
    by_id = run_modb(fresh_db, "export", "id:1", process=False)
    by_name = run_modb(fresh_db, "export", "c/1", process=False)
    assert by_id.returncode == by_name.returncode == 0
    assert "Frames: 146" in by_id.stdout and by_name.stdout != by_id.stdout
    r = run_modb(fresh_db, "export", "id:1", "--out", tmp_path / "missing" / "x.bvh")
    assert r.returncode == 1 and "cannot write" in r.stderr
