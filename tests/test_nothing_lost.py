"""Nothing silently lost: a clip of any length gets its snippets, a file whose snippets cannot be
built fails (rolled back, non-zero exit), and --keep-going reports every file whatever happens to
one, a lost connection included."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import psycopg
from support.commands import run_modb
from support.data import mocap
from support.databases import counts
from support.long_clip import repeat_bvh
from support.snippet_oracle import clip_terms

WALK = ("bandai-1", "data", "dataset-1_walk_active_001.bvh")


def _terminators(db, mirrored: bool) -> tuple[np.ndarray, np.ndarray]:
    """Frames and features of the stored terminators, the features read from the cubes' text (a
    point's: "(x1, ..., x49)"; tens of thousands of rows: one parse, not 49 calls a row)."""
    rows = db.execute(
        "SELECT frame, features::text FROM modb.terminators WHERE mirrored = %s ORDER BY frame",
        [mirrored],
    ).fetchall()
    features = np.array(",".join(r[1][1:-1] for r in rows).split(","), dtype=float)
    return np.array([r[0] for r in rows]), features.reshape(len(rows), 49)


def _stored(db):
    """The clip's skeleton and frames as stored (binary: the real[] values themselves)."""
    hierarchy, joint_map, rotations, translations, fps = (
        db.cursor(binary=True)
        .execute(
            "SELECT s.hierarchy, s.joint_map, v.rotations, v.translations, v.fps "
            "FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id"
        )
        .fetchone()
    )
    return hierarchy, joint_map, np.asarray(rotations, float), np.asarray(translations, float), fps


def test_a_long_clip_gets_every_snippet(fresh_db, db, tmp_path):
    """40,000 frames (0.8.0 lost them all past the jsonb size limit, with exit 0): every window is a
    snippet, and every terminator's features are an independent whole-clip computation's (scipy),
    across the chunks the server computes them in."""
    clip = repeat_bvh(mocap(*WALK), tmp_path / "long_walk.bvh", 40_000)
    r = run_modb(fresh_db, "load", clip, "-q", process=False)
    assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
    hierarchy, joint_map, rotations, translations, fps = _stored(db)
    length, stride = round(0.5 * fps) + 1, max(1, round(fps / 30))
    firsts = np.arange(0, len(rotations) - length + 1, stride)
    snippets = db.execute(
        "SELECT first_frame, n_frames, future_translation IS NOT NULL FROM modb.snippets "
        "ORDER BY first_frame"
    ).fetchall()
    assert [s[0] for s in snippets] == firsts.tolist()
    assert {s[1] for s in snippets} == {length} and all(s[2] for s in snippets)
    frames, features = _terminators(db, mirrored=False)
    assert frames.tolist() == sorted(set(firsts.tolist()) | set((firsts + length - 1).tolist()))
    oracle = clip_terms(hierarchy, joint_map, rotations, translations, fps)
    difference = np.abs(features - oracle.feat[frames])
    assert difference.max() < 1e-4, (difference.max(), frames[difference.max(axis=1).argmax()])


def test_a_long_mirror_image_matches_the_whole_clips(fresh_db, db, tmp_path):
    """The mirror image of a clip cut in chunks: its reflections come from the whole clip's
    statistics summed chunk by chunk, so its terminators are those of the whole clip mirrored at
    once."""
    from modb_kernel import mirror

    clip = repeat_bvh(mocap(*WALK), tmp_path / "mirrored_walk.bvh", 9_000)
    r = run_modb(fresh_db, "load", clip, "--mirror", "-q", process=False)
    assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
    hierarchy, joint_map, rotations, translations, fps = _stored(db)
    joints = hierarchy["joints"]
    names = [j["name"] for j in joints]
    (pairs,) = db.execute("SELECT mirror_pairs FROM modb.skeletons").fetchone()
    mirrored = mirror.mirror(
        [j["parent"] for j in joints],
        [j["offset"] for j in joints],
        [j["end_site"] for j in joints],
        mirror.partner_index(names, pairs),
        rotations,
        translations,
        hierarchy["translated"],
    )
    oracle = clip_terms(hierarchy, joint_map, *mirrored, fps)
    frames, features = _terminators(db, mirrored=True)
    assert (len(frames),) == db.execute(
        "SELECT count(*) FROM modb.terminators WHERE NOT mirrored"
    ).fetchone()
    assert np.abs(features - oracle.feat[frames]).max() < 1e-4


def _unmappable(tmp_path, name: str):
    """A real walk whose joints carry names no joint map knows."""
    text = mocap(*WALK).read_text()
    names = [
        line.split()[1] for line in text.splitlines() if line.split()[:1] in (["ROOT"], ["JOINT"])
    ]
    for k, joint in enumerate(sorted(names, key=len, reverse=True)):
        text = text.replace(f" {joint}\n", f" part{k}\n")
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_file_whose_snippets_cannot_be_built_fails(fresh_db, db, tmp_path):
    good = mocap("bandai-1", "data", "dataset-1_walk_normal_001.bvh")
    bad = _unmappable(tmp_path, "unmapped.bvh")
    r = run_modb(fresh_db, "load", bad, good, "--keep-going", "--collection", "c", "--units", "cm")
    assert r.returncode == 1, r.stderr
    assert "loaded without snippets" not in r.stderr
    assert f"{bad}: its snippets could not be built" in r.stderr and "joint map" in r.stderr
    assert "--no-snippets" in r.stderr
    # the good file is loaded with its snippets; nothing of the bad one stays
    assert db.execute("SELECT array_agg(name) FROM modb.clips").fetchone()[0] == [good.stem]
    assert counts(db)[3] == 1
    r = run_modb(fresh_db, "load", bad, "--no-snippets", "--collection", "c", "--units", "cm")
    assert r.returncode == 0, r.stderr
    assert counts(db)[3] == 2


def _deep_bvh(path, depth: int):
    """A chain of `depth` joints: the old recursive parser died of it without naming the file."""
    lines = [
        "HIERARCHY",
        "ROOT r",
        "{",
        " OFFSET 0 0 0",
        " CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for k in range(depth):
        lines += [f"JOINT j{k}", "{", " OFFSET 0 1 0", " CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", " OFFSET 0 1 0", "}"] + ["}"] * (depth + 1)
    channels = 6 + 3 * depth
    lines += ["MOTION", "Frames: 1", "Frame Time: 0.0333333", " ".join(["0"] * channels)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_keep_going_reports_every_file(fresh_db, db, tmp_path):
    folder = tmp_path / "batch"
    folder.mkdir()
    for name in ("a_walk.bvh", "c_walk.bvh"):
        (folder / name).write_bytes(mocap(*WALK).read_bytes())
    _deep_bvh(folder / "b_deep.bvh", 1200)
    r = run_modb(fresh_db, "load", folder, "--keep-going")
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode == 1
    assert "3 files: 2 clip versions loaded" in r.stdout, r.stdout
    assert "1 file(s) not loaded:" in r.stderr and str(folder / "b_deep.bvh") in r.stderr
    assert sorted(n for (n,) in db.execute("SELECT name FROM modb.clips")) == ["a_walk", "c_walk"]


def test_a_lost_connection_is_reported_for_each_remaining_file(cluster, fresh_db, db, tmp_path):
    folder = tmp_path / "many"
    folder.mkdir()
    files = sorted(mocap("bandai-1", "data").glob("dataset-1_walk*.bvh"))[:30]
    for f in files:
        (folder / f.name).write_bytes(f.read_bytes())
    (dbname,) = db.execute("SELECT current_database()").fetchone()
    load = subprocess.Popen(
        [sys.executable, "-m", "modb.cli", "--dsn", fresh_db, "load", folder, "--keep-going"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        deadline = time.monotonic() + 120
        while db.execute("SELECT count(*) FROM modb.clips").fetchone()[0] < 3:
            assert time.monotonic() < deadline and load.poll() is None
            time.sleep(0.05)
        admin.execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
            "WHERE datname = %s AND pid <> %s",
            [dbname, db.info.backend_pid],
        )
    out, err = load.communicate(timeout=300)
    assert "Traceback" not in err, err
    assert load.returncode == 1
    loaded = db.execute("SELECT count(*) FROM modb.clips").fetchone()[0]
    assert loaded < len(files), "the load ended before the connection was cut: use more files"
    lost = [line for line in err.splitlines() if "the connection was lost" in line]
    # each file not loaded says so once (in the progress and again in the final list)
    not_loaded = {f.name for f in files} - {
        n for (n,) in db.execute("SELECT name || '.bvh' FROM modb.clips")
    }
    for name in not_loaded:
        assert sum(name in line for line in lost) == 2, (name, lost)
    assert f"{len(files)} files: {loaded} clip versions loaded" in out, out


def test_an_unbuildable_graph_says_why(fresh_db, db):
    r = run_modb(fresh_db, "load", mocap(*WALK), process=False)
    assert r.returncode == 0, r.stderr
    r = run_modb(fresh_db, "graph", "build", "g", "-q")
    assert r.returncode == 1 and "turn 45 degrees each way" in r.stderr, r.stderr
    assert "invalid input syntax" not in r.stderr
    assert db.execute("SELECT count(*) FROM modb.graphs").fetchone()[0] == 0
