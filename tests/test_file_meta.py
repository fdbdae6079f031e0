"""What the loader stores in a version's meta (issue 25): a sidecar X.annotations.json's segments
and tags, Bandai Namco's own X.json content and style labels as tags, the dataset's licence (issue
41), and a new version's meta carried over from the previous one (its annotations only when the
frame count is the same)."""

from __future__ import annotations

import json
import shutil

from support.commands import run_modb
from support.data import mocap


def stored_meta(db, name: str) -> list[tuple[int, int, dict]]:
    return db.execute(
        "SELECT v.version, v.n_frames, v.meta FROM modb.clip_versions v "
        "JOIN modb.clips c ON c.id = v.clip_id WHERE c.name = %s ORDER BY v.version",
        [name],
    ).fetchall()


def test_bandai_labels_become_tags(fresh_db, db):
    data = mocap("bandai-1", "data")
    files = sorted(data.glob("dataset-1_walk*_00[12].bvh"))[:3]
    r = run_modb(fresh_db, "load", *files, "--collection", "b1", "--no-snippets", "-q")
    assert r.returncode == 0, r.stderr
    cfg = data.parent / "cfg"
    for f in files:
        ids = json.loads(f.with_suffix(".json").read_text())
        labels = [
            (cfg / f"{key}_label.txt").read_text().splitlines()[ids[key]].split("_", 1)[1]
            for key in ("content", "style")
        ]
        ((_, _, meta),) = stored_meta(db, f.stem)
        licence = data.parent / "LICENSE"  # the dataset's terms, a folder above its files
        title = next(line.strip() for line in licence.read_text().splitlines() if line.strip())
        assert meta == {"tags": labels, "licence": title, "licence_file": str(licence.resolve())}
        assert labels[0] in f.stem and labels[1] in f.stem  # the file's own name agrees


def test_a_sidecar_annotates_and_a_bad_one_stores_nothing(fresh_db, db, tmp_path):
    walk = tmp_path / "walk.bvh"
    shutil.copy(mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh"), walk)
    side = tmp_path / "walk.annotations.json"
    segments = [
        {"name": "left step", "start": 0, "end": 14},
        {"name": "turn", "start": 10, "end": 40},
    ]
    side.write_text(json.dumps({"annotations": segments[::-1], "tags": ["mine"]}))
    r = run_modb(fresh_db, "load", walk, "--collection", "w", "--no-snippets", "-q")
    assert r.returncode == 0, r.stderr
    ((_, n, meta),) = stored_meta(db, "walk")
    assert meta == {"annotations": segments, "tags": ["mine"]}
    # a segment past the last frame: the load fails, naming the sidecar, and stores nothing
    other = tmp_path / "other.bvh"
    shutil.copy(walk, other)
    (tmp_path / "other.annotations.json").write_text(
        json.dumps({"annotations": [{"name": "late", "start": 0, "end": n}]})
    )
    r = run_modb(fresh_db, "load", other, "--collection", "w", "--no-snippets", "-q")
    assert r.returncode != 0
    assert "other.annotations.json" in r.stderr and "late" in r.stderr
    assert stored_meta(db, "other") == []


def test_a_new_version_keeps_the_meta_and_a_shorter_one_only_the_tags(fresh_db, db, tmp_path):
    walk = tmp_path / "walk.bvh"
    shutil.copy(mocap("bandai-2-dev", "data", "dataset-2_walk_active_002.bvh"), walk)
    load = ["load", walk, "--collection", "w", "--no-snippets"]
    assert run_modb(fresh_db, *load, "-q").returncode == 0
    r = run_modb(fresh_db, "annotate", "w/walk", "--segment", "stride:3-30")
    assert r.returncode == 0, r.stderr
    db.execute(
        'UPDATE modb.clip_versions SET meta = meta || \'{"tags": ["kept"]}\' '
        "WHERE clip_id = (SELECT id FROM modb.clips WHERE name = 'walk')"
    )
    db.commit()
    lines = walk.read_text().splitlines()
    lines[-1] = lines[-1].replace("0", "1", 1)  # one value of the last frame: same length
    walk.write_text("\n".join(lines) + "\n")
    r = run_modb(fresh_db, *load)
    assert r.returncode == 0 and "carried over from version 1" in r.stderr, r.stderr
    frames = next(i for i, line in enumerate(lines) if line.startswith("Frames:"))
    n = int(lines[frames].split()[1])
    lines[frames] = f"Frames: {n - 1}"
    walk.write_text("\n".join(lines[:-1]) + "\n")  # one frame fewer
    r = run_modb(fresh_db, *load)
    assert r.returncode == 0 and "version 2's annotations stay with it" in r.stderr, r.stderr
    versions = stored_meta(db, "walk")
    assert [v[1] for v in versions] == [n, n, n - 1]
    first = {"annotations": [{"name": "stride", "start": 3, "end": 30}], "tags": ["kept"]}
    assert [v[2] for v in versions] == [first, first, {"tags": ["kept"]}]
