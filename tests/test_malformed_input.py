"""Malformed BVH and ASF/AMC input: each case is a real file mutated at run time, and each must be
refused with a MotionFileError naming file and line (never another exception), or, where the
format allows it, read correctly."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import counts

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.loader.errors import MotionFileError
from modb.loader.limits import FPS_RANGE, MAX_JOINT_DEPTH

WALK = ("bandai-1", "data", "dataset-1_walk_active_001.bvh")  # 22 joints, 146 frames, 30 fps
HEAD_DEPTH = 6  # joint_Root, Hips, Spine, Chest, Neck, Head


def _lines(*parts: str) -> list[str]:
    return mocap(*parts).read_text().splitlines()


def _write(path, lines: list[str]):
    path.write_text("\n".join(lines) + "\n")
    return path


def _index(lines: list[str], text: str, nth: int = 0) -> int:
    """0-based index of the nth line that starts with `text` once stripped."""
    return [k for k, line in enumerate(lines) if line.strip().startswith(text)][nth]


def _refusal(read, *args) -> MotionFileError:
    with pytest.raises(MotionFileError) as caught:
        read(*map(str, args))
    return caught.value


def _assert_at(e: MotionFileError, path, line: int | None, words: str) -> None:
    assert e.path == str(path) and e.line == line, str(e)
    where = f"{path}:{line}: " if line else f"{path}: "
    assert str(e).startswith(where) and words in str(e), str(e)


def _walk_with(tmp_path, name: str, edit) -> tuple[object, list[str]]:
    lines = _lines(*WALK)
    edit(lines)
    return _write(tmp_path / name, lines), lines


def _set_frame_time(value: str):
    def edit(lines):
        lines[_index(lines, "Frame Time:")] = f"Frame Time: {value}"

    return edit


# --- 1. frame rates ---------------------------------------------------------------------------


@pytest.mark.parametrize("frame_time", ["1e-320", "5e-324", "1e-300", "1e-12", "3600", "1.5"])
def test_bvh_frame_rate_outside_the_range_is_refused_at_its_line(tmp_path, frame_time):
    """1e-320 and 5e-324 overflowed (OverflowError), 1e-300 and 1e-12 were stored as 1e300 and
    1e12 fps, 3600 was left to a database check constraint."""
    path, lines = _walk_with(tmp_path, "rate.bvh", _set_frame_time(frame_time))
    e = _refusal(read_bvh, path)
    _assert_at(e, path, _index(lines, "Frame Time:") + 1, "outside the accepted 1 to 1,000 fps")


@pytest.mark.parametrize("frame_time, fps", [("0.001", 1000.0), ("1", 1.0), ("0.0333333", 30.0)])
def test_bvh_frame_rates_at_the_ends_of_the_range_load(tmp_path, frame_time, fps):
    assert FPS_RANGE == (1.0, 1000.0)
    path, _ = _walk_with(tmp_path, "rate.bvh", _set_frame_time(frame_time))
    assert read_bvh(str(path)).fps == fps


@pytest.fixture
def trial(tmp_path):
    """A private copy of CMU 131's skeleton and trial 01 (its first 50 frames)."""
    folder = tmp_path / "131"
    folder.mkdir()
    shutil.copy(mocap("cmu", "131", "131.asf"), folder / "131.asf")
    amc = _lines("cmu", "131", "131_01.amc")
    frames = [k for k, line in enumerate(amc) if line.strip().isdigit()]
    _write(folder / "131_01.amc", amc[: frames[50]])
    return folder


@pytest.mark.parametrize("fps", [0.5, 1000.5, 1e12, float("inf"), float("nan")])
def test_amc_frame_rate_outside_the_range_is_refused_naming_the_option(trial, fps):
    amc = trial / "131_01.amc"
    e = _refusal(lambda p, a: read_amc(p, read_asf(a), fps), amc, trial / "131.asf")
    _assert_at(e, amc, None, "(--fps) is outside the accepted 1 to 1,000 fps")


def test_amc_frame_rates_at_the_ends_of_the_range_load(trial):
    asf = read_asf(str(trial / "131.asf"))
    for fps in FPS_RANGE:
        assert read_amc(str(trial / "131_01.amc"), asf, fps).fps == fps


# --- 2. whitespace in the MOTION header ---------------------------------------------------------


@pytest.mark.parametrize(
    "frames, frame_time",
    [
        ("Frames:\t146", "Frame\tTime:\t0.0333333"),
        ("Frames: 146", "Frame \t Time:0.0333333"),
        ("Frames :146", "Frame  Time :  0.0333333"),
        ("\tFrames:   146\t", "  Frame\t\tTime:\t\t0.0333333  "),
    ],
)
def test_bvh_header_takes_any_whitespace_between_and_after_its_words(tmp_path, frames, frame_time):
    def edit(lines):
        at = _index(lines, "MOTION")
        lines[at + 1 : at + 3] = [frames, frame_time]

    path, _ = _walk_with(tmp_path, "header.bvh", edit)
    motion = read_bvh(str(path))
    reference = read_bvh(str(mocap(*WALK)))
    assert motion.n_frames == 146 and motion.fps == 30.0
    assert np.array_equal(motion.rotations, reference.rotations)


def test_bvh_header_words_are_still_required(tmp_path):
    path, lines = _walk_with(
        tmp_path, "header.bvh", lambda L: L.__setitem__(_index(L, "Frame Time:"), "FrameTime: 0.1")
    )
    e = _refusal(read_bvh, path)
    _assert_at(e, path, _index(lines, "FrameTime:") + 1, "expected 'Frame Time: ...' after MOTION")


# --- 3. deep hierarchies ------------------------------------------------------------------------


def _nest_under_head(depth: int):
    """A chain of `depth` joints without channels below Head (the motion lines stay valid)."""

    def edit(lines):
        at = _index(lines, "JOINT Head") + 3  # its CHANNELS line
        chain = []
        for n in range(depth):
            chain += [f"JOINT deep{n}", "{", "OFFSET 0 0.1 0", "CHANNELS 0"]
        lines[at + 1 : at + 1] = chain + ["}"] * depth

    return edit


def test_bvh_deeper_than_the_limit_is_refused_at_the_joint(tmp_path):
    """1,000 joints deep was a RecursionError, without file or line."""
    path, lines = _walk_with(tmp_path, "deep.bvh", _nest_under_head(1000))
    e = _refusal(read_bvh, path)
    first_too_deep = MAX_JOINT_DEPTH - HEAD_DEPTH  # deep0 is at depth HEAD_DEPTH + 1
    _assert_at(
        e,
        path,
        _index(lines, f"JOINT deep{first_too_deep}") + 1,
        f"is {MAX_JOINT_DEPTH + 1} joints deep, more than the {MAX_JOINT_DEPTH} accepted",
    )


def test_bvh_200_joints_deep_loads(tmp_path):
    path, _ = _walk_with(tmp_path, "deep.bvh", _nest_under_head(200))
    motion = read_bvh(str(path))
    assert len(motion.skeleton.joints) == 22 + 200 and motion.n_frames == 146
    deepest = motion.skeleton.index("deep199")
    head = motion.skeleton.index("Head")
    positions = motion.world_positions()[0]
    # the chain runs 200 x 0.1 cm along Head's rest y axis; Head's rotation turns it
    assert np.linalg.norm(positions[deepest] - positions[head]) == pytest.approx(0.2)


# --- 4. the ASF hierarchy -----------------------------------------------------------------------


def _asf_with(trial, edit) -> tuple[object, list[str]]:
    path = trial / "131.asf"
    lines = path.read_text().splitlines()
    edit(lines)
    return _write(path, lines), lines


def _hierarchy_line(lines: list[str], text: str) -> int:
    return next(k for k, line in enumerate(lines) if line.strip() == text) + 1


HIERARCHY_CASES = {
    # a loop away from root: lhipjoint's leg hangs from its own toes
    "cycle": (
        [
            ("root lhipjoint rhipjoint lowerback", "root rhipjoint lowerback"),
            ("", "ltoes lhipjoint"),
        ],
        "ltoes lhipjoint",
        "the :hierarchy has a cycle: ltoes -> lhipjoint -> lfemur -> ltibia -> lfoot -> ltoes",
    ),
    "own_parent": (
        [("lhipjoint lfemur", "lhipjoint lfemur lhipjoint")],
        "lhipjoint lfemur lhipjoint",
        "bone 'lhipjoint' is given as its own parent",
    ),
    "root_as_child": (
        [("lfoot ltoes", "lfoot ltoes root")],
        "lfoot ltoes root",
        "root is given as a child of lfoot",
    ),
    "second_parent": (
        [("rhipjoint rfemur", "rhipjoint rfemur lfemur")],
        "rhipjoint rfemur lfemur",
        "bone 'lfemur' is given a second parent, rhipjoint",
    ),
}


def _edit_hierarchy(replacements):
    def edit(lines):
        for old, new in replacements:
            if old:
                k = next(k for k, line in enumerate(lines) if line.strip() == old)
                lines[k] = "    " + new
            else:  # a new line at the end of the hierarchy
                lines.insert(len(lines) - 1, "    " + new)

    return edit


@pytest.mark.parametrize("case", HIERARCHY_CASES)
def test_asf_hierarchy_errors_name_their_line(trial, case):
    """The cycle, own parent and root-as-child were a RecursionError; the second parent was stored
    as 35 joints with 31 names."""
    replacements, line_text, words = HIERARCHY_CASES[case]
    path, lines = _asf_with(trial, _edit_hierarchy(replacements))
    e = _refusal(read_asf, path)
    _assert_at(e, path, _hierarchy_line(lines, line_text), words)


def _chain_bones(depth: int):
    """`depth` bones without dofs chained below root (the AMC needs no line for them)."""

    def edit(lines):
        bones = []
        for n in range(depth):
            bones += ["  begin", f"     name chain{n}", "     direction 0 1 0", "     length 0.1"]
            bones += ["     axis 0 0 0 XYZ", "  end"]
        at = _index(lines, ":hierarchy")
        edges = ["    root chain0"] + [f"    chain{n} chain{n + 1}" for n in range(depth - 1)]
        lines[at + 2 : at + 2] = edges  # after 'begin'
        lines[at:at] = bones

    return edit


def test_asf_deep_chains_load_up_to_the_limit_without_recursion(trial):
    """1,000 bones deep was a RecursionError; 200 deep loads, past the limit is refused."""
    path, lines = _asf_with(trial, _chain_bones(1000))
    e = _refusal(read_asf, path)
    too_deep = MAX_JOINT_DEPTH - 1  # root is 1 deep, chain0 2
    _assert_at(
        e,
        path,
        _hierarchy_line(lines, f"chain{too_deep - 1} chain{too_deep}"),
        f"bone chain{too_deep} is {MAX_JOINT_DEPTH + 1} joints deep",
    )
    shutil.copy(mocap("cmu", "131", "131.asf"), path)
    _asf_with(trial, _chain_bones(200))
    motion = read_amc(str(trial / "131_01.amc"), read_asf(str(path)))
    assert len(motion.skeleton.joints) == 31 + 200 and motion.n_frames == 50


# --- 5. repeated channels -----------------------------------------------------------------------


def test_asf_repeated_dof_is_refused_at_its_line(trial):
    """`dof rx rx rz` was stored with rotation order XXZ."""
    path, lines = _asf_with(
        trial, lambda L: L.__setitem__(_index(L, "dof rx ry rz"), "dof rx rx rz")
    )
    e = _refusal(read_asf, path)
    _assert_at(e, path, _index(lines, "dof rx rx rz") + 1, "dof rx appears twice on bone lfemur")


def test_asf_repeated_root_channel_is_refused_at_its_line(trial):
    """`order TX TX TZ RX RY RZ` was stored, and the root's Y translation dropped."""
    order = "order TX TX TZ RX RY RZ"
    path, lines = _asf_with(trial, lambda L: L.__setitem__(_index(L, "order"), order))
    e = _refusal(read_asf, path)
    _assert_at(e, path, _index(lines, order) + 1, "root channel TX appears twice")


@pytest.mark.parametrize("where", ["axis 0 0 20", "axis XYZ"])  # lfemur's, the root's
def test_asf_axis_order_with_a_repeated_axis_is_refused_at_its_line(trial, where):
    at = []

    def edit(lines):
        at.append(_index(lines, where))
        lines[at[0]] = lines[at[0]].replace("XYZ", "XXZ")

    path, _ = _asf_with(trial, edit)
    e = _refusal(read_asf, path)
    _assert_at(e, path, at[0] + 1, "axis order 'XXZ' is not a permutation of XYZ")


def test_bvh_repeated_channel_is_refused_at_its_line(tmp_path):
    def edit(lines):
        k = _index(lines, "CHANNELS", 3)
        lines[k] = lines[k].replace(
            "Zrotation Xrotation Yrotation", "Xrotation Xrotation Zrotation"
        )

    path, lines = _walk_with(tmp_path, "channels.bvh", edit)
    e = _refusal(read_bvh, path)
    _assert_at(e, path, _index(lines, "CHANNELS", 3) + 1, "channel Xrotation appears twice")


# --- lengths beyond reason, and line numbers that match the editor's -----------------------------


def test_offsets_and_positions_beyond_reason_are_refused_at_their_line(tmp_path, trial):
    path, lines = _walk_with(
        tmp_path,
        "far.bvh",
        lambda L: L.__setitem__(_index(L, "OFFSET", 2), "OFFSET 15.7357 1e300 0"),
    )
    _assert_at(_refusal(read_bvh, path, "cm"), path, _index(lines, "OFFSET", 2) + 1, "beyond the")
    amc = trial / "131_01.amc"
    amc_lines = amc.read_text().splitlines()
    k = _index(amc_lines, "root", 7)
    amc_lines[k] = "root 5.2 1e305 -33.8 10.4 9.8 -5.4"
    _write(amc, amc_lines)
    e = _refusal(lambda p, a: read_amc(p, read_asf(a)), amc, trial / "131.asf")
    _assert_at(e, amc, k + 1, "root Y position of frame 8 is")


def test_line_numbers_count_only_real_line_breaks(tmp_path):
    """A form feed or a Latin-1 0x85 byte inside a line must not shift the lines after it."""
    lines = _lines(*WALK)
    lines[2] = lines[2] + "\x0c"  # '{' of the root
    lines[5] = lines[5] + " \x85"  # JOINT Hips (0x85 is a line break to str.splitlines)
    at = _index(lines, "MOTION") + 10
    lines[at] = "abc " + lines[at].split(" ", 1)[1]
    path = tmp_path / "breaks.bvh"
    path.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
    e = _refusal(read_bvh, path)
    _assert_at(e, path, at + 1, "is 'abc', not a number")


def test_utf16_file_with_a_byte_order_mark_loads(tmp_path):
    path = tmp_path / "utf16.bvh"
    path.write_bytes(mocap(*WALK).read_text().encode("utf-16"))
    assert read_bvh(str(path)).n_frames == 146


# --- through the command line: exit non-zero, file:line, no traceback, nothing stored -----------


def _assert_cli_refuses(fresh_db, db, load, where: str, words: str, *options: str) -> None:
    r = run_modb(fresh_db, "load", load, *options)
    assert r.returncode == 1, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr, r.stderr
    assert where in r.stderr and words in r.stderr, r.stderr
    assert counts(db) == (0, 0, 0, 0)


def test_cli_refuses_a_subnormal_frame_time(fresh_db, db, tmp_path):
    path, lines = _walk_with(tmp_path, "rate.bvh", _set_frame_time("1e-320"))
    line = _index(lines, "Frame Time:") + 1
    _assert_cli_refuses(fresh_db, db, path, f"{path}:{line}: ", "outside the accepted")


def test_cli_refuses_a_hierarchy_1000_joints_deep(fresh_db, db, tmp_path):
    path, lines = _walk_with(tmp_path, "deep.bvh", _nest_under_head(1000))
    line = _index(lines, f"JOINT deep{MAX_JOINT_DEPTH - HEAD_DEPTH}") + 1
    _assert_cli_refuses(fresh_db, db, path, f"{path}:{line}: ", "joints deep")


def test_cli_refuses_an_asf_bone_with_two_parents(fresh_db, db, trial):
    replacements, line_text, words = HIERARCHY_CASES["second_parent"]
    path, lines = _asf_with(trial, _edit_hierarchy(replacements))
    where = f"{path}:{_hierarchy_line(lines, line_text)}: "
    _assert_cli_refuses(fresh_db, db, trial / "131_01.amc", where, words)


def test_cli_refuses_an_asf_repeated_root_channel(fresh_db, db, trial):
    order = "order TX TX TZ RX RY RZ"
    path, lines = _asf_with(trial, lambda L: L.__setitem__(_index(L, "order"), order))
    where = f"{path}:{_index(lines, order) + 1}: "
    _assert_cli_refuses(fresh_db, db, trial / "131_01.amc", where, "appears twice")


def test_cli_refuses_an_amc_rate_outside_the_range(fresh_db, db, trial):
    """Up front, once for the whole call (not once per AMC file)."""
    for fps in ("5000", "nan", "0.5"):
        # a process: the interpreter's exit status (a subprocess smoke test)
        r = run_modb(fresh_db, "load", trial / "131_01.amc", "--fps", fps, process=True)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert f"argument --fps: must be a number from 1 to 1000 fps, got '{fps}'" in r.stderr
    assert counts(db) == (0, 0, 0, 0)
