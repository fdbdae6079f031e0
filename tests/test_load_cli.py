"""`modb load`: summaries, idempotent re-loads, versions, and bad files that leave nothing
behind."""

from __future__ import annotations

import builtins
import io
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import mocap
from support.databases import counts

from modb.loader.bvh import read_bvh
from modb.loader.ingest import load_files
from modb.loader.reading import ReadOptions
from modb.loader.sources import find_sources

WALK = ("bandai-1", "data", "dataset-1_walk_active_001.bvh")


def test_directory_load_summary_and_idempotent_reload(fresh_db, db):
    src = mocap("cmu", "131", "bvh")
    r = run_modb(fresh_db, "load", src, "--units", "0.0564444")
    assert r.returncode == 0, r.stderr
    assert "3 files: 3 clip versions loaded (3,343 frames" in r.stdout
    assert "--units 0.0564444: 0.0564444 m per unit" in r.stderr
    assert "frames/s" in r.stdout
    before = counts(db)
    assert before == (1, 1, 3, 3)  # one collection named after the folder, one shared skeleton
    assert (
        db.execute("SELECT modb.collection_path(collection_id) FROM modb.clips LIMIT 1").fetchone()[
            0
        ]
        == "bvh"
    )
    r = run_modb(fresh_db, "load", src, "--units", "0.0564444")
    assert r.returncode == 0 and "0 clip versions loaded" in r.stdout and "3 unchanged" in r.stdout
    assert counts(db) == before
    # --units auto and cm mean the same for these files... but not for CMU: explicit factors only.
    # The same bytes read with other units are other motion: a new version.
    r = run_modb(fresh_db, "load", src / "131_01.bvh", "--units", "in")
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout
    assert db.execute("SELECT max(version) FROM modb.clip_versions").fetchone()[0] == 2


def test_units_auto_states_its_rule_and_refuses_to_guess(fresh_db, db):
    r = run_modb(fresh_db, "load", mocap(*WALK))
    assert r.returncode == 0
    assert "units auto: rest pose spans" in r.stderr and "-> cm (0.01 m per unit)" in r.stderr
    r = run_modb(fresh_db, "load", mocap("cmu", "131", "bvh", "131_01.bvh"), process=True)
    assert r.returncode == 1  # the process's exit status (a subprocess smoke test)
    assert "131_01.bvh: cannot infer units" in r.stderr and "--units" in r.stderr
    assert counts(db)[2] == 1


def _corrupt(tmp_path, name: str, edit) -> str:
    lines = mocap(*WALK).read_text().splitlines()
    edit(lines)
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _motion_at() -> int:
    return mocap(*WALK).read_text().splitlines().index("MOTION")


def _cut_value(k: int):
    return lambda L: L.__setitem__(k, " ".join(L[k].split()[:-1]))


def _replace_value(k: int, word: str):
    return lambda L: L.__setitem__(
        k, " ".join(word if n == 4 else w for n, w in enumerate(L[k].split()))
    )


# (edit of the lines, expected message, expected 1-based line) given the 0-based index of 'MOTION'.
BAD_BVH = {
    "short_line": lambda m: (
        _cut_value(m + 10),
        "frame 8 has 131 values, the hierarchy declares 132",
        m + 11,
    ),
    "not_a_number": lambda m: (
        _replace_value(m + 5, "abc"),
        "value 5 of frame 3 is 'abc', not a number",
        m + 6,
    ),
    "frame_count": lambda m: (
        lambda L: L.__setitem__(m + 1, "Frames: 500"),
        "declares 500 frames",
        m + 2,
    ),
    "channel": lambda m: (
        lambda L: L.__setitem__(4, L[4].replace("Zrotation", "Qrotation")),
        "unknown channel 'Qrotation'",
        5,
    ),
    "truncated_hierarchy": lambda m: (
        lambda L: L.__delitem__(slice(40, None)),
        "file ends inside the hierarchy",
        40,
    ),
    "blank_line_inside": lambda m: (
        lambda L: L.insert(m + 20, ""),
        "declares 146 frames but 145 frame lines",
        m + 2,
    ),
}


@pytest.mark.parametrize("case", BAD_BVH)
def test_bad_file_names_file_and_line_and_stores_nothing(fresh_db, db, tmp_path, case):
    edit, expect, line = BAD_BVH[case](_motion_at())
    # a blank line is skipped, so drop a frame to make the count wrong
    if case == "blank_line_inside":
        edit = (lambda e: lambda L: (e(L), L.pop()))(edit)
    bad = _corrupt(tmp_path, f"{case}.bvh", edit)
    r = run_modb(fresh_db, "load", bad)
    assert r.returncode == 1
    assert f"{bad}:{line}: " in r.stderr and expect in r.stderr, r.stderr
    assert counts(db) == (0, 0, 0, 0)


def test_blank_lines_and_byte_order_mark_are_tolerated(tmp_path):
    lines = mocap(*WALK).read_text().splitlines()
    lines.insert(_motion_at() + 20, "   ")
    p = tmp_path / "bom.bvh"
    p.write_bytes(b"\xef\xbb\xbf" + ("\n".join(lines) + "\n").encode())
    assert read_bvh(str(p)).n_frames == 146


def test_keep_going_loads_the_good_and_lists_the_bad(fresh_db, db, tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    shutil.copy(mocap(*WALK), folder / "a_good.bvh")
    shutil.copy(mocap("bandai-1", "data", "dataset-1_run_active_001.bvh"), folder / "c_good.bvh")
    bad = _corrupt(folder, "b_bad.bvh", lambda L: L.__setitem__(L.index("MOTION") + 1, "Frames: 3"))
    r = run_modb(fresh_db, "load", folder)
    assert r.returncode == 1 and "stopped at the first bad file; 1 not tried" in r.stderr
    assert counts(db)[3] == 1
    r = run_modb(fresh_db, "load", folder, "--keep-going")
    assert r.returncode == 1
    assert "1 file(s) not loaded" in r.stderr and str(bad) in r.stderr
    assert (
        "1 clip versions loaded" in r.stdout
        and "1 unchanged" in r.stdout
        and "1 failed" in r.stdout
    )
    assert counts(db)[3] == 2


def test_one_transaction_per_file(fresh_db, db):
    """A refusal at the last step (the version row) leaves no collection, skeleton or clip
    behind."""
    db.execute("""CREATE FUNCTION public.refuse() RETURNS trigger LANGUAGE plpgsql AS
                  $$ BEGIN RAISE EXCEPTION 'refused by test'; END $$""")
    db.execute(
        "CREATE TRIGGER refuse BEFORE INSERT ON modb.clip_versions FOR EACH ROW EXECUTE FUNCTION "
        "public.refuse()"
    )
    r = run_modb(fresh_db, "load", mocap(*WALK))
    assert r.returncode == 1 and "refused by test" in r.stderr
    assert counts(db) == (0, 0, 0, 0)


def test_real_world_bvh_quirks(tmp_path):
    """CRLF, tabs, '.5'-style numbers, colons in names, mixed rotation orders, position channels
    anywhere."""
    src = mocap(*WALK)
    text = src.read_text()
    names = [
        line.split()[1] for line in text.splitlines() if line.split()[:1] in (["ROOT"], ["JOINT"])
    ]
    quirky = text
    for n in sorted(names, key=len, reverse=True):
        quirky = quirky.replace(f"JOINT {n}\n", f"JOINT rig:{n}\n").replace(
            f"ROOT {n}\n", f"ROOT rig:{n}\n"
        )
    quirky = quirky.replace("  ", "\t").replace("0.0333333", ".0333333").replace("\n", "\r\n")
    p = tmp_path / "quirky.bvh"
    p.write_bytes(quirky.encode())
    motion = read_bvh(str(p))
    assert motion.fps == 30.0 and all(n.startswith("rig:") for n in motion.skeleton.names)
    assert motion.skeleton.joint_map["pelvis"] == "rig:Hips"
    assert ("rig:UpperArm_L", "rig:UpperArm_R") in motion.skeleton.mirror_pairs
    assert len(motion.skeleton.mirror_pairs) == 8
    ref_names, expected = bvhio_world_positions(str(src), 0.01)
    ours = in_order([n[4:] for n in motion.skeleton.names], ref_names, motion.world_positions())
    assert np.abs(ours - expected).max() < 0.001
    # Every Bandai joint has position channels: all 22 carry a translation.
    assert motion.translations.shape[1] == len(names) == 22


def test_rotation_orders_and_partial_channels(tmp_path):
    """A hand-written file with XYZ, YXZ and single-axis joints, checked against bvhio."""
    p = tmp_path / "orders.bvh"
    p.write_text(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition "
        "Xrotation Yrotation Zrotation\n"
        " JOINT Spine\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Yrotation Xrotation Zrotation\n"
        "  JOINT Neck\n  {\n   OFFSET 0 12 1\n   CHANNELS 2 Yposition Zrotation\n"
        "   End Site\n   {\n    OFFSET 0 8 0\n   }\n  }\n }\n"
        " JOINT Leg\n {\n  OFFSET 9 -5 0\n  CHANNELS 1 Xrotation\n  End Site\n  {\n   OFFSET 0 -40 "
        "0\n  }\n }\n}\n"
        "MOTION\nFrames: 3\nFrame Time: .5\n"
        "1 90 2 10 20 30 5 -40 60 15 45 -30\n"
        "2 91 3 -80 60 -170 120 5 -10 14 -90 100\n"
        "-3 92 .5 0 0 0 0 0 0 12 0 175\n"
    )
    motion = read_bvh(str(p), "cm")
    names, expected = bvhio_world_positions(str(p), 0.01)
    assert (
        np.abs(in_order(motion.skeleton.names, names, motion.world_positions()) - expected).max()
        < 1e-6
    )  # bvhio computes in float32
    assert [j.rotation_order for j in motion.skeleton.joints] == ["XYZ", "YXZ", "Z", "X"]


def test_units_spelled_differently_but_equal_store_nothing_new(fresh_db, db):
    walk = mocap(*WALK)
    assert run_modb(fresh_db, "load", walk).returncode == 0  # auto -> cm
    r = run_modb(fresh_db, "load", walk, "--units", "cm")
    assert r.returncode == 0 and "1 unchanged" in r.stdout, r.stdout
    r = run_modb(fresh_db, "load", walk, "--units", "0.0100")
    assert r.returncode == 0 and "1 unchanged" in r.stdout, r.stdout
    assert counts(db)[3] == 1


def test_collection_keeps_subfolders_and_refuses_collisions(fresh_db, db, tmp_path):
    for sub, src in (("s1", WALK), ("s2", ("bandai-1", "data", "dataset-1_run_active_001.bvh"))):
        (tmp_path / "coll" / sub).mkdir(parents=True)
        shutil.copy(mocap(*src), tmp_path / "coll" / sub / "x.bvh")
    r = run_modb(fresh_db, "load", tmp_path / "coll", "--collection", "flat")
    assert r.returncode == 0, r.stderr
    assert sorted(
        db.execute("SELECT collection || '/' || name FROM modb.current_clips").fetchall()
    ) == [("flat/s1/x",), ("flat/s2/x",)]
    r = run_modb(
        fresh_db,
        "load",
        tmp_path / "coll" / "s1" / "x.bvh",
        tmp_path / "coll" / "s2" / "x.bvh",
        "--collection",
        "one",
    )
    assert r.returncode == 2 and "would both become clip one/x" in r.stderr
    assert counts(db)[3] == 2


def test_new_versions_replace_their_snippets_and_other_ids_stay(fresh_db, db, tmp_path):
    walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    run = mocap("bandai-1", "data", "dataset-1_run_active_001.bvh")
    assert run_modb(fresh_db, "load", walk, run, "--collection", "c").returncode == 0
    snippets = (
        "SELECT c.name, s.version, array_agg(s.id ORDER BY s.id) FROM modb.snippets s "
        "JOIN modb.clips c ON c.id = s.clip_id GROUP BY 1, 2 ORDER BY 1, 2"
    )
    before = {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()}
    assert run_modb(fresh_db, "load", walk, run, "--collection", "c").returncode == 0  # nothing new
    assert db.execute("SELECT modb.build_snippets()").fetchone()[0] == 0
    assert {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()} == before
    changed = tmp_path / walk.name
    lines = walk.read_text().splitlines()
    lines[lines.index("MOTION") + 3] = " ".join(
        "0" for _ in lines[lines.index("MOTION") + 3].split()
    )
    changed.write_text("\n".join(lines) + "\n")
    r = run_modb(fresh_db, "load", changed, "--collection", "c")
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout
    after = {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()}
    run_key = ("dataset-1_run_active_001", 1)
    assert after[run_key] == before[run_key]  # other clips keep their snippet ids
    assert ("dataset-1_walk_active_001", 1) not in after and (
        "dataset-1_walk_active_001",
        2,
    ) in after
    assert len(after[("dataset-1_walk_active_001", 2)]) == len(
        before[("dataset-1_walk_active_001", 1)]
    )


class _CountedFile:
    """An open file whose reads add up the bytes they return, per path."""

    def __init__(self, f, path: Path, bytes_read: Counter):
        self._f, self._path, self._bytes_read = f, path, bytes_read

    def read(self, *args):
        data = self._f.read(*args)
        self._bytes_read[self._path] += len(data)
        return data

    def readinto(self, buffer):
        n = self._f.readinto(buffer)
        self._bytes_read[self._path] += n or 0
        return n

    def __iter__(self):
        for line in self._f:
            self._bytes_read[self._path] += len(line)
            yield line

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()


def test_the_loader_reads_each_file_once(db, monkeypatch):
    """A load reads each file's bytes once: hashed and parsed from the same read (not opened again
    to parse), an ASF once for the AMC files that share it, and Bandai Namco's label files once
    for the clips they label. Every open() and Path.open() of the files is counted, with the bytes
    read through it."""
    trial = mocap("cmu", "131")
    walks = [mocap(*WALK), mocap("bandai-1", "data", "dataset-1_walk_normal_001.bvh")]
    files = [*walks, trial / "131_01.amc", trial / "131_02.amc", trial / "131.asf"]
    labels = [mocap("bandai-1", "cfg", f"{key}_label.txt") for key in ("content", "style")]
    watched = {f.resolve() for f in [*files, *labels]}
    opened: Counter = Counter()
    bytes_read: Counter = Counter()
    real_open = io.open

    def counting_open(file, *args, **kwargs):
        f = real_open(file, *args, **kwargs)
        if isinstance(file, (str, Path)) and Path(file).resolve() in watched:
            opened[Path(file).resolve()] += 1
            return _CountedFile(f, Path(file).resolve(), bytes_read)
        return f

    monkeypatch.setattr(io, "open", counting_open)  # Path.open, read_bytes, read_text
    monkeypatch.setattr(builtins, "open", counting_open)
    sources = find_sources([str(f) for f in files], None)
    summary = load_files(db, sources, ReadOptions(), keep_going=False, snippets=False)
    monkeypatch.undo()
    assert [r.status for r in summary.results] == ["loaded"] * 4, summary.failed
    tagged = db.execute("SELECT count(*) FROM modb.clip_versions WHERE meta ? 'tags'").fetchone()
    assert tagged == (2,)  # both walks took their tags from the label files read once
    assert opened == {f: 1 for f in watched}
    assert bytes_read == {f: f.stat().st_size for f in watched}
