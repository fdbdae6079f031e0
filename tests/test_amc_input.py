"""ASF/AMC input: pairing, quirks of real files, and every malformed case refused with file and
line."""

from __future__ import annotations

import shutil

import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import counts


@pytest.fixture
def trial(tmp_path):
    """A private copy of CMU 131's skeleton and trial 01, to damage."""
    folder = tmp_path / "131"
    folder.mkdir()
    shutil.copy(mocap("cmu", "131", "131.asf"), folder / "131.asf")
    shutil.copy(mocap("cmu", "131", "131_01.amc"), folder / "131_01.amc")
    return folder


def _edit(path, edit):
    lines = path.read_text().splitlines()
    edit(lines)
    path.write_text("\n".join(lines) + "\n")


def _line_of(path, prefix: str, nth: int = 0) -> int:
    hits = [k for k, line in enumerate(path.read_text().splitlines()) if line.startswith(prefix)]
    return hits[nth]


def test_real_quirks_comment_lines_exponents_and_truncation(fresh_db, db):
    quirks = mocap("cmu", "quirks")
    # a comment line inside the motion; paired as S.asf
    r = run_modb(fresh_db, "load", quirks / "11_01.amc")
    assert r.returncode == 0, r.stderr
    golf = quirks / "golf_01.amc"  # last frame cut short: 19 of 29 bone lines; values like e-014
    r = run_modb(fresh_db, "load", golf)
    assert r.returncode == 1
    assert (
        f"{golf}:" in r.stderr
        and "lacks 10 of 29 bone lines" in r.stderr
        and "--allow-truncated" in r.stderr
    )
    assert counts(db)[3] == 1
    r = run_modb(fresh_db, "load", golf, "--allow-truncated")
    assert r.returncode == 0, r.stderr
    assert "warning:" in r.stderr and "dropped the last frame" in r.stderr
    frame_numbers = sum(1 for line in golf.read_text().splitlines() if line.strip().isdigit())
    n_complete = frame_numbers - 1  # all but the cut one
    (stored,) = db.execute(
        "SELECT n_frames FROM modb.current_clips WHERE name = 'golf_01'"
    ).fetchone()
    assert stored == n_complete


def test_fps_default_and_option(fresh_db, db, trial):
    assert run_modb(fresh_db, "load", trial / "131_01.amc").returncode == 0
    assert (
        run_modb(
            fresh_db, "load", trial / "131_01.amc", "--fps", "60", "--collection", "slow"
        ).returncode
        == 0
    )
    rates = dict(db.execute("SELECT collection, fps FROM modb.current_clips").fetchall())
    assert rates == {"131": 120.0, "slow": 60.0}


@pytest.mark.parametrize(
    "case",
    [
        "wrong_count",
        "unknown_bone",
        "not_a_number",
        "empty",
        "not_motion",
        "bad_dof",
        "truncated_middle",
    ],
)
def test_bad_amc_or_asf_names_file_and_line_and_stores_nothing(fresh_db, db, trial, case):
    amc, asf = trial / "131_01.amc", trial / "131.asf"
    bad, expect = amc, None
    if case == "wrong_count":
        k = _line_of(amc, "lfemur ", 5)
        _edit(amc, lambda L: L.__setitem__(k, L[k] + " 1.0"))
        expect, line = "bone lfemur has 4 values, its dof needs 3", k + 1
    elif case == "unknown_bone":
        k = _line_of(amc, "lfemur ", 7)
        _edit(amc, lambda L: L.__setitem__(k, L[k].replace("lfemur", "lfemurx")))
        expect, line = "bone 'lfemurx' is not in the skeleton", k + 1
    elif case == "not_a_number":
        k = _line_of(amc, "ltibia ", 9)
        _edit(amc, lambda L: L.__setitem__(k, "ltibia 12.x5"))
        expect, line = "value '12.x5' of bone ltibia is not a number", k + 1
    elif case == "empty":
        amc.write_text("")
        expect, line = "no frames", 1
    elif case == "not_motion":
        amc.write_text("hello, this is not motion capture\n")
        expect, line = "expected a frame number", 1
    elif case == "bad_dof":
        k = _line_of(asf, "    dof rx ry rz")
        _edit(asf, lambda L: L.__setitem__(k, "    dof rx ry rw"))
        bad, expect, line = asf, "unsupported dof 'rw'", k + 1
    elif case == "truncated_middle":
        k = _line_of(amc, "ltoes ", 3)
        _edit(amc, lambda L: L.__delitem__(k))
        expect, line = "frame 4 lacks 1 of 29 bone lines (ltoes)", None
    r = run_modb(fresh_db, "load", amc)
    assert r.returncode == 1
    assert expect in r.stderr, r.stderr
    where = f"{bad}:{line}:" if line else f"{bad}:"
    assert where in r.stderr, r.stderr
    assert counts(db) == (0, 0, 0, 0)


def test_pairing_rules(fresh_db, db, tmp_path):
    quirks = mocap("cmu", "quirks")
    a = tmp_path / "a"
    a.mkdir()
    shutil.copy(quirks / "11_01.amc", a / "take.amc")
    shutil.copy(quirks / "11.asf", a / "11.asf")
    shutil.copy(quirks / "golf.asf", a / "golf.asf")
    # two skeletons beside it, no S_NN name: refuse, say how
    r = run_modb(fresh_db, "load", a / "take.amc")
    assert r.returncode == 2 and "cannot tell which ASF" in r.stderr and "--asf FILE" in r.stderr
    r = run_modb(fresh_db, "load", a / "take.amc", a / "11.asf")  # the one .asf named in the call
    assert r.returncode == 0, r.stderr
    r = run_modb(fresh_db, "load", a / "take.amc", "--asf", a / "11.asf", "--collection", "forced")
    assert r.returncode == 0, r.stderr
    b = tmp_path / "b"
    b.mkdir()
    shutil.copy(quirks / "11_01.amc", b / "11_01.amc")
    shutil.copy(quirks / "11.asf", b / "11.asf")
    shutil.copy(quirks / "golf.asf", b / "golf.asf")
    r = run_modb(fresh_db, "load", b)  # S.asf for S_NN.amc; ASF files themselves are not clips
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout, r.stdout + r.stderr
    assert counts(db)[3] == 3


def test_keep_going_mixes_formats(fresh_db, db, trial):
    shutil.copy(mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh"), trial / "walk.bvh")
    # its last frame is cut short
    shutil.copy(mocap("cmu", "quirks", "golf_01.amc"), trial / "131_99.amc")
    r = run_modb(fresh_db, "load", trial, "--keep-going")
    assert r.returncode == 1
    assert "131_99.amc" in r.stderr and "1 file(s) not loaded" in r.stderr
    assert "2 clip versions loaded" in r.stdout
