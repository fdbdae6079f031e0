"""Hardening of the command line and the Python API: `--out` onto a FIFO, a character device, a
symlink, a regular file, a directory or standard output, and numeric arguments bounded (no NaN,
infinities, non-positive values where they make no sense, or values beyond the stated maximum)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import stat
import subprocess
import sys
import threading
import time

import psycopg
import pytest
from support.data import mocap
from support.databases import scratch_database

from modb.cli import build_parser
from modb.loader.bvh import read_bvh
from modb.output import open_output

WALKS = (
    "dataset-1_walk_normal_001.bvh",
    "dataset-1_walk_normal_002.bvh",
    "dataset-1_walk_active_001.bvh",
    "dataset-1_walk_old_001.bvh",
)
TIMEOUT = 120  # seconds: a command that writes where it should not, or never ends, fails


@pytest.fixture(scope="module")
def walks(cluster):
    """A database of a few Bandai dataset 1 walks, with snippets; and the first clip's id."""
    files = [mocap("bandai-1", "data", name) for name in WALKS]
    with scratch_database(cluster, f"hardening_{os.getpid()}") as dsn:
        r = modb(dsn, "load", *files, "--collection", "walks", "-q")
        assert r.returncode == 0, r.stderr
        with psycopg.connect(dsn) as conn:
            (clip,) = conn.execute("SELECT min(clip_id) FROM modb.current_clips").fetchone()
        yield dsn, str(clip)


def modb(dsn: str, *args, timeout: float = TIMEOUT, cwd=None) -> subprocess.CompletedProcess:
    """The real command line (as support.commands.run_modb), killed after `timeout` seconds."""
    return subprocess.run(
        [sys.executable, "-m", "modb.cli", "--dsn", dsn, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=cwd,
    )


def export_args(clip: str, out) -> list:
    return ["export", clip, "--out", out]


def synth_args(out, *more) -> list:
    return [
        "synth",
        "--to",
        "0,3",
        "--seconds",
        "2",
        "--exclude-seconds",
        "0",
        "-q",
        "--out",
        out,
        *more,
    ]


# Every command that writes a file: (name, its arguments writing `out`, what `out` holds).
WRITERS = {
    "export": lambda clip, out, tmp: export_args(clip, out),
    "synth": lambda clip, out, tmp: synth_args(out),
    "synth --report-json": lambda clip, out, tmp: synth_args(
        tmp / "strip.bvh", "--report-json", out
    ),
}


def check_content(writer: str, data: bytes, tmp_path) -> None:
    """`data` is what the writer writes: a BVH that reads back, or the report's JSON."""
    if writer == "synth --report-json":
        report = json.loads(data)
        assert report["chain"] and "report" in report
        return
    assert data.startswith(b"HIERARCHY\n")
    copy = tmp_path / "read-back.bvh"
    copy.write_bytes(data)
    assert read_bvh(str(copy)).n_frames > 1


def leftovers(folder) -> list[str]:
    return sorted(name for name in os.listdir(folder) if "partial" in name)


class FifoReader:
    """Reads everything written into a FIFO, in a thread, until the last writer closes it.

    It holds a write end of its own (O_RDWR: on Linux that opens without waiting for a reader), so
    that its own reading end opens at once and the writer under test never waits for a reader;
    `finish` closes it after the writer is done, and the reader then sees the end of the data. If
    the command replaced the FIFO instead of writing into it, the reader gets nothing.
    """

    def __init__(self, path) -> None:
        self.holder = os.open(path, os.O_RDWR)
        self.fd = os.open(path, os.O_RDONLY)
        self.chunks: list[bytes] = []
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        while chunk := os.read(self.fd, 1 << 16):
            self.chunks.append(chunk)

    def finish(self) -> bytes:
        os.close(self.holder)
        self.thread.join(TIMEOUT)
        assert not self.thread.is_alive(), "the FIFO's reader never saw the end of the data"
        os.close(self.fd)
        return b"".join(self.chunks)


@pytest.mark.parametrize("via_symlink", [False, True], ids=["fifo", "symlink-to-fifo"])
@pytest.mark.parametrize("writer", WRITERS)
def test_a_fifo_as_out_is_written_into_and_stays_a_fifo(walks, tmp_path, writer, via_symlink):
    dsn, clip = walks
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    out = fifo
    if via_symlink:
        out = tmp_path / "link"
        os.symlink("pipe", out)
    reader = FifoReader(fifo)
    try:
        r = modb(dsn, *WRITERS[writer](clip, out, tmp_path))
    finally:
        data = reader.finish()
    assert r.returncode == 0, r.stderr
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode), "the FIFO was replaced"
    if via_symlink:
        assert os.path.islink(out) and os.readlink(out) == "pipe"
    check_content(writer, data, tmp_path)
    assert leftovers(tmp_path) == []


def character_device(path) -> None:
    """A node like /dev/null (character device 1, 3) at `path`; skips where none can be made."""
    if os.geteuid() != 0:
        pytest.skip("making a character device (mknod) needs root")
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("this system refuses mknod (no CAP_MKNOD)")
    try:
        with open(path, "w") as f:
            f.write("probe")
    except PermissionError:
        pytest.skip(f"the file system of {path} is mounted nodev: its devices cannot be opened")


@pytest.mark.parametrize("writer", WRITERS)
def test_a_character_device_as_out_is_written_into_and_stays_a_device(walks, tmp_path, writer):
    dsn, clip = walks
    device = tmp_path / "fakenull"
    character_device(device)
    r = modb(dsn, *WRITERS[writer](clip, device, tmp_path))
    assert r.returncode == 0, r.stderr
    st = os.lstat(device)
    assert stat.S_ISCHR(st.st_mode) and st.st_rdev == os.makedev(1, 3), "the device was replaced"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("writer", WRITERS)
@pytest.mark.parametrize("existing", [True, False], ids=["to-a-file", "dangling"])
def test_a_symlink_as_out_stays_a_symlink_and_its_target_gets_the_content(
    walks, tmp_path, writer, existing
):
    dsn, clip = walks
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    target = elsewhere / "real"
    if existing:
        target.write_text("old content\n")
    link = tmp_path / "link"
    os.symlink("elsewhere/real", link)  # relative: resolved from the link's folder
    r = modb(dsn, *WRITERS[writer](clip, link, tmp_path))
    assert r.returncode == 0, r.stderr
    assert os.path.islink(link) and os.readlink(link) == "elsewhere/real"
    check_content(writer, target.read_bytes(), tmp_path)
    assert leftovers(tmp_path) == [] and leftovers(elsewhere) == []


@pytest.mark.parametrize("writer", WRITERS)
def test_a_symlink_target_keeps_its_directory_entry(walks, tmp_path, writer):
    """Written in place: the target keeps its inode, so a hard link to it sees the new content."""
    dsn, clip = walks
    target, hard = tmp_path / "real", tmp_path / "hard"
    target.write_text("old content\n")
    os.link(target, hard)
    inode = target.stat().st_ino
    link = tmp_path / "link"
    os.symlink(target, link)
    r = modb(dsn, *WRITERS[writer](clip, link, tmp_path))
    assert r.returncode == 0, r.stderr
    assert target.stat().st_ino == inode and hard.read_bytes() == target.read_bytes()
    check_content(writer, target.read_bytes(), tmp_path)


@pytest.mark.parametrize("writer", WRITERS)
def test_a_regular_file_as_out_is_replaced_atomically(walks, tmp_path, writer):
    dsn, clip = walks
    folder = tmp_path / "out"
    folder.mkdir()
    out = folder / "result"
    out.write_text("old content\n")
    out.chmod(0o640)
    with open(out) as old:
        r = modb(dsn, *WRITERS[writer](clip, out, tmp_path))
        assert r.returncode == 0, r.stderr
        # A rename over the old file, not a rewrite of it: what had it open still reads it whole.
        assert old.read() == "old content\n"
    check_content(writer, out.read_bytes(), tmp_path)
    assert stat.S_IMODE(os.stat(out).st_mode) == 0o640, "the file's permissions were not kept"
    assert os.listdir(folder) == ["result"], "a temporary file was left behind"


def test_export_to_a_fifo_writes_the_same_bytes_as_to_a_file(walks, tmp_path):
    dsn, clip = walks
    r = modb(dsn, "export", clip, "--out", tmp_path / "file.bvh")
    assert r.returncode == 0, r.stderr
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    try:
        r = modb(dsn, "export", clip, "--out", fifo)
    finally:
        data = reader.finish()
    assert r.returncode == 0, r.stderr
    assert data == (tmp_path / "file.bvh").read_bytes()
    r = modb(dsn, "export", clip)  # and to standard output
    assert r.stdout.encode() == data


@pytest.mark.parametrize(
    "args",
    [
        lambda clip, d: export_args(clip, d),
        lambda clip, d: synth_args(d),
        lambda clip, d: synth_args(d / "strip.bvh", "--report-json", d),
    ],
    ids=["export", "synth", "synth --report-json"],
)
def test_a_directory_as_out_is_a_clear_error_before_any_work(walks, tmp_path, args):
    dsn, clip = walks
    folder = tmp_path / "folder"
    folder.mkdir()
    (folder / "kept").write_text("kept\n")
    started = time.monotonic()
    r = modb(dsn, *args(clip, folder))
    assert r.returncode == 1, r.stderr  # as for any file that cannot be written
    assert f"cannot write {folder}: is a directory" in r.stderr
    assert time.monotonic() - started < 30
    assert sorted(os.listdir(folder)) == ["kept"] and leftovers(tmp_path) == []
    assert not (tmp_path / "strip.bvh").exists(), "synthesized before finding it cannot write"


def test_synth_writes_standard_output_with_a_dash(walks, tmp_path):
    dsn, _ = walks
    work = tmp_path / "work"  # where a file named "-" would appear
    work.mkdir()
    r = modb(dsn, *synth_args("-"), cwd=work)
    assert r.returncode == 0, r.stderr
    check_content("synth", r.stdout.encode(), tmp_path)
    assert "standard output" in r.stderr
    r = modb(dsn, *synth_args(tmp_path / "strip.bvh", "--report-json", "-"), cwd=work)
    assert r.returncode == 0, r.stderr
    check_content("synth --report-json", r.stdout.encode(), tmp_path)
    assert os.listdir(work) == []


@pytest.mark.parametrize(
    "more", [["--report"], ["--report-json", "-"]], ids=["--report", "--report-json -"]
)
def test_synth_refuses_two_outputs_on_standard_output(walks, tmp_path, more):
    dsn, _ = walks
    r = modb(dsn, *synth_args("-", *more), timeout=30, cwd=tmp_path)
    assert r.returncode == 2 and "cannot share standard output" in r.stderr, r.stderr
    assert r.stdout == "" and os.listdir(tmp_path) == []


def test_a_failed_write_leaves_the_old_file_and_no_temporary_file(tmp_path):
    out = tmp_path / "result.bvh"
    out.write_text("old content\n")
    with pytest.raises(RuntimeError), open_output(out) as f:
        f.write("half a file")
        raise RuntimeError("interrupted")
    assert out.read_text() == "old content\n" and os.listdir(tmp_path) == ["result.bvh"]
    with pytest.raises(IsADirectoryError):
        with open_output(tmp_path):
            pass
    assert os.listdir(tmp_path) == ["result.bvh"]


def test_a_symlink_is_replaced_only_when_asked(tmp_path):
    (tmp_path / "real").write_text("kept\n")
    link = tmp_path / "link"
    os.symlink("real", link)
    with open_output(link, replace_symlink=True) as f:
        f.write("new\n")
    assert not os.path.islink(link) and link.read_text() == "new\n"
    assert (tmp_path / "real").read_text() == "kept\n"
    long_name = tmp_path / ("x" * 255)  # the temporary name still fits the folder
    with open_output(long_name) as f:
        f.write("long\n")
    assert long_name.read_text() == "long\n" and len(os.listdir(tmp_path)) == 3


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs Linux's /proc/self/fd")
def test_open_descriptors_named_in_proc_are_written_into(tmp_path):
    """/dev/stdout and /dev/fd/N lead to /proc/self/fd/N: written into, whatever they are open on
    (a pipe, a regular file), never replaced."""
    read_end, write_end = os.pipe()
    with open_output(f"/proc/self/fd/{write_end}") as f:
        f.write("through the pipe\n")
    os.close(write_end)
    assert os.read(read_end, 100) == b"through the pipe\n"
    os.close(read_end)
    out = tmp_path / "redirected"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        with open_output(f"/proc/self/fd/{fd}") as f:
            f.write("into the open file\n")
        assert os.fstat(fd).st_ino == os.stat(out).st_ino  # the same file, not a new one
    finally:
        os.close(fd)
    assert out.read_text() == "into the open file\n" and os.listdir(tmp_path) == ["redirected"]


# --- numeric arguments --------------------------------------------------------------------------

SYNTH = ["synth", "--to", "1,2", "--out", "x.bvh"]
SYNTH_SECONDS = [*SYNTH, "--seconds", "5"]
NOT_FINITE = ["inf", "-inf", "nan", "1e308"]

# (the command's other arguments, the option, values it refuses)
BOUNDED = [
    (SYNTH, "--seconds", [*NOT_FINITE, "-1", "0", "3600.5", "abc"]),
    (SYNTH_SECONDS, "--arrival-radius", [*NOT_FINITE, "-1", "0", "101"]),
    (SYNTH_SECONDS, "--exclude-seconds", [*NOT_FINITE, "-1", "3601"]),
    (SYNTH_SECONDS, "--lead-time", [*NOT_FINITE, "-0.1", "2.5"]),
    (SYNTH_SECONDS, "--blend", ["inf", "nan", "-1", "1001", "1.5", "1e308"]),
    (SYNTH_SECONDS, "--start", ["inf", "0", "-1", str(2**63), "1.5"]),
    (["export", "1"], "--version", ["inf", "nan", "0", "-1", str(2**31), "1.5"]),
    (["graph", "build", "g"], "--min-turn", [*NOT_FINITE, "-1", "180.5"]),
    (["serve"], "--port", ["inf", "nan", "0", "-1", "65536", "80x", "1e308"]),
    (["bench", "load"], "--rounds", ["inf", "nan", "0", "-1", "1001"]),
    (["bench", "select"], "--queries", ["inf", "nan", "0", "-1", "100001"]),
    (["bench", "select"], "--seed", ["inf", "nan", "-1", str(2**32)]),
    (["bench", "synth"], "--seconds", [*NOT_FINITE, "-1", "0", "3601"]),
    (["bench", "synth"], "--seed", ["nan", "-1"]),
    (["bench", "scale"], "--queries", ["inf", "0", "-1", "100001"]),
    (["bench", "scale"], "--baseline-queries", ["inf", "-1", "100001"]),
    (["bench", "scale"], "--pgbench-seconds", ["inf", "nan", "0", "-1", "3601"]),
    (["bench", "scale"], "--seed", ["-1"]),
    (["bench", "scale"], "--sizes", ["0", "10,-5", "inf", "nan", "20000000", "10,,20", "some"]),
]
CASES = [
    pytest.param(base, option, value, id=f"{' '.join(base[:2])} {option} {value}")
    for base, option, values in BOUNDED
    for value in values
]


def refused(argv: list[str], capsys) -> str:
    """argparse's refusal of `argv` (exit status 2): its message."""
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args(argv)
    assert e.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize("base,option,value", CASES)
def test_out_of_range_numbers_are_refused_naming_the_option(base, option, value, capsys):
    message = refused([*base, f"{option}={value}"], capsys)  # =: "-inf" is no option name
    assert f"argument {option}: must be " in message and repr(value) in message, message


@pytest.mark.parametrize(
    "argv",
    [
        [*SYNTH, "--seconds", "3600", "--lead-time", "2", "--arrival-radius", "100"],
        [*SYNTH, "--seconds", "0.5", "--exclude-seconds", "0", "--blend", "1000", "--start", "1"],
        ["export", "1", "--version", str(2**31 - 1)],
        ["graph", "build", "g", "--min-turn", "0"],
        ["graph", "build", "g", "--min-turn", "180"],
        ["serve", "--port", "65535"],
        ["bench", "scale", "--sizes", "1,all,10000000", "--baseline-queries", "0"],
        ["bench", "synth", "--seconds", "3600", "--seed", "0"],
        ["bench", "select", "--seed", str(2**32 - 1), "--queries", "100000"],
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
def test_the_limits_themselves_are_accepted(argv):
    build_parser().parse_args(argv)


def test_the_ranges_are_in_the_help(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["synth", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "at most 3600" in text and "0-2 seconds" in text


def subcommands(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield name, sub
                for deeper, subsub in subcommands(sub):
                    yield f"{name} {deeper}", subsub


def commands() -> list:
    return [name for name, _ in subcommands(build_parser())]


@pytest.mark.parametrize("command", commands())
def test_no_option_takes_an_unbounded_number(command):
    parser = dict(subcommands(build_parser()))[command]
    plain = [
        a.option_strings[0] if a.option_strings else a.dest
        for a in parser._actions
        if a.type in (int, float)
    ]
    assert plain == [], f"modb {command}: {plain} take any int/float (inf, nan, -1, 1e308, ...)"


@pytest.mark.parametrize("value", ["inf", "nan", "1e308", "-1", "0"])
def test_synth_seconds_out_of_range_fail_at_once_naming_the_option(walks, tmp_path, value):
    dsn, _ = walks
    started = time.monotonic()
    r = modb(
        dsn, *synth_args(tmp_path / "x.bvh")[:4], value, "--out", tmp_path / "x.bvh", timeout=30
    )
    assert r.returncode == 2 and "argument --seconds: must be" in r.stderr, r.stderr
    assert time.monotonic() - started < 20 and not (tmp_path / "x.bvh").exists()


# --- the Python API -----------------------------------------------------------------------------


class NoConnection:
    """Stands in for a connection that a refused request must never use."""

    def __getattr__(self, name):
        raise AssertionError(f"the connection was used ({name}) for a request to refuse")


BAD_SETTINGS = [
    ("arrival_radius", [math.inf, math.nan, 0.0, -1.0, 1e308, "0.5", None]),
    ("exclude_seconds", [math.inf, math.nan, -1.0, 1e308]),
    ("lead_time", [math.inf, -math.inf, math.nan, -0.1, 5.0]),
    ("blend_frames", [math.inf, math.nan, -1, 10**9, 1.5, True]),
]


@pytest.mark.parametrize(
    "name,value",
    [pytest.param(n, v, id=f"{n}={v!r}") for n, values in BAD_SETTINGS for v in values],
)
def test_settings_refuse_non_finite_and_out_of_range_values(name, value):
    from modb import Settings

    with pytest.raises(ValueError, match=name):
        Settings(**{name: value})
    settings = Settings()
    with pytest.raises(ValueError, match=name):
        setattr(settings, name, value)  # settings change while an avatar plays: checked too
    assert getattr(settings, name) == getattr(Settings(), name)


@pytest.mark.parametrize("seconds", [math.inf, math.nan, 1e308, -1.0, 0.0, 3601.0, "5"])
def test_synthesize_refuses_seconds_out_of_range_before_any_query(seconds):
    from modb import Settings
    from modb.synthesis.synth import synthesize

    with pytest.raises(ValueError, match="seconds"):
        synthesize(NoConnection(), [(0.0, 3.0)], seconds, Settings())


@pytest.mark.parametrize(
    "kwargs",
    [
        {"position": (math.nan, 0.0, 0.0)},
        {"position": (0.0, 0.0, math.inf)},
        {"position": (0.0, 0.0)},
        {"position": (1e7, 0.0, 0.0)},
        {"heading": math.inf},
        {"heading": math.nan},
        {"start_snippet": 0},
        {"start_snippet": -1},
        {"start_snippet": 1.5},
        {"goals": [(1e308, 0.0)]},
        {"goals": [(0.0, math.nan)]},
    ],
    ids=repr,
)
def test_the_avatar_refuses_non_finite_and_out_of_range_values(kwargs):
    from modb import Avatar

    with pytest.raises(ValueError):
        Avatar(NoConnection(), **kwargs)


def test_goals_far_beyond_any_floor_are_refused():
    from modb.synthesis.chain import checked_goal

    assert checked_goal((1e6, -1e6)) == (1e6, -1e6)
    for goal in [(1e6 + 1, 0.0), (0.0, -1e308), (0.0, 5.0, math.inf)]:
        with pytest.raises(ValueError, match="metres"):
            checked_goal(goal)


@pytest.mark.parametrize("command", ["export", "synth"])
def test_a_reader_that_leaves_early_is_no_failure(walks, command):
    """`modb export X | head` exits 0, as `modb list | head` does (the pipe closes early)."""
    dsn, clip = walks
    args = [clip] if command == "export" else ["--to", "0,3", "--seconds", "20", "--out", "-"]
    read = subprocess.Popen(
        [sys.executable, "-m", "modb.cli", "--dsn", dsn, command, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert read.stdout.readline() == b"HIERARCHY\n"
    read.stdout.close()  # as head does after its lines
    assert read.wait(timeout=TIMEOUT) == 0, read.stderr.read()
    assert b"Traceback" not in read.stderr.read()


def test_edit_scripts_are_checked_before_they_are_stored(walks):
    """`modb edit save` refuses what is not a script (naming the command); `modb edit list`
    survives a script stored unchecked."""
    dsn, _ = walks
    r = modb(dsn, "edit", "save", "junk", "--commands", '[1, "x", null]')
    assert r.returncode != 0 and "command 1: each command is an object" in r.stderr, r.stderr
    r = modb(dsn, "edit", "save", "fast", "--commands", '[{"op": "resample", "fps": 9999}]')
    assert r.returncode != 0 and "fps" in r.stderr, r.stderr
    with psycopg.connect(dsn, autocommit=True) as conn:
        with contextlib.suppress(psycopg.errors.CheckViolation):  # a table that refuses it: fine
            conn.execute(
                "INSERT INTO modb.edit_scripts (name, commands) VALUES ('stored raw', %s)",
                [json.dumps([1, "x", None])],
            )
    r = modb(dsn, "edit", "save", "first10", "--commands", '[{"op": "trim", "start": 0, "end": 9}]')
    assert r.returncode == 0, r.stderr
    listed = modb(dsn, "edit", "list")
    assert listed.returncode == 0 and "first10: trim" in listed.stdout, listed.stderr


def test_a_clip_named_twice_is_edited_once(walks):
    """A clip named twice, or named and in a named collection, gets one new version."""
    dsn, _ = walks
    r = modb(dsn, "edit", "save", "first10", "--commands", '[{"op": "trim", "start": 0, "end": 9}]')
    assert r.returncode == 0, r.stderr
    walk = mocap("bandai-1", "data", WALKS[0])
    assert modb(dsn, "load", walk, "--collection", "edited once", "-q").returncode == 0
    with psycopg.connect(dsn) as conn:
        (clip,) = conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'edited once'"
        ).fetchone()
    r = modb(dsn, "edit", "apply", "first10", clip, clip, "edited once")
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [f"clip {clip}: version 2 (10 frames, " + r.stdout.split(
        "10 frames, ", 1)[1].splitlines()[0]]  # fmt: skip
    with psycopg.connect(dsn) as conn:
        versions = conn.execute(
            "SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s", [clip]
        ).fetchone()[0]
    assert versions == 2
