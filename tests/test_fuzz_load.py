"""Seeded fuzzing of the BVH and ASF/AMC readers on mutations of real files.

Every mutated file must either parse into a valid Motion or be refused with a MotionFileError that
names it; nothing else may escape a reader. A subset then goes through `modb load --keep-going`
into one database, whose rows must be exactly the files the summary reports as loaded.
"""

from __future__ import annotations

import json
import random
import re
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from support.commands import run_modb
from support.data import CMU_UNITS, mocap

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.loader.errors import MotionFileError
from modb.loader.limits import FPS_RANGE, MAX_LENGTH_M
from modb.motion import Motion

SEED = 20261201
N_FILES = 300  # mutated files read by the parsers
N_LOADED = 60  # of those, loaded through the command line
BVH_FRAMES = 40  # the real files are cut to their first frames, so 300 reads stay fast
AMC_FRAMES = 80

BVH_SOURCES = (  # (path parts, units for read_bvh)
    (("bandai-1", "data", "dataset-1_walk_active_001.bvh"), "auto"),
    (("bandai-1", "data", "dataset-1_bow_angry_001.bvh"), "auto"),
    (("bandai-1", "data", "dataset-1_run_active_001.bvh"), "auto"),
    (("cmu", "131", "bvh", "131_01.bvh"), CMU_UNITS),  # End Sites, 3-channel joints
)
AMC_SOURCES = (  # (ASF, AMC)
    (("cmu", "131", "131.asf"), ("cmu", "131", "131_01.amc")),
    (("cmu", "quirks", "11.asf"), ("cmu", "quirks", "11_01.amc")),  # a comment line
    (("cmu", "01", "01.asf"), ("cmu", "01", "01_01.amc")),  # CRLF line ends
)

NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
ODD_NUMBERS = (
    "1e308", "-1e308", "1e999", "1e-320", "5e-324", "1e-300", "nan", "NaN", "inf", "-inf",
    "-0", "0", "-1", "-7.5", "3600", "123456789012345678901234567890", "1e12", "0x10", "1_000",
    "--1", "1.2.3", "", "١٢",
)  # fmt: skip
GARBAGE = (
    "{", "}", "{ }", "JOINT", "ROOT", "End Site", "OFFSET", "CHANNELS", "CHANNELS 6", "MOTION",
    "Frames:", "@@", "\x00", "é", "\u2028", "\x0c", "\t", ":", "begin", "end", "root", "dof rx",
    ":hierarchy", ":bonedata", "#", "Xrotation", "name", "1 2 3",
)  # fmt: skip
KEYWORDS = {
    "HIERARCHY": ("hierarchy", "HIERARCH", "MOTION"),
    "ROOT": ("JOINT", "Root", "ROOT ROOT"),
    "JOINT": ("ROOT", "Joint", "End Site", "JOINT JOINT"),
    "OFFSET": ("OFFSETS", "CHANNELS", "offset"),
    "CHANNELS": ("CHANNEL", "OFFSET", "CHANNELS 7"),
    "End": ("END", "JOINT"),
    "Site": ("Sight", "{"),
    "MOTION": ("MOTIONS", "HIERARCHY", "motion"),
    "Frames:": ("Frames", "Frame:", "Frames: Frames:", "Frame Time:"),
    "Time:": ("Time", "Times:", "Time::"),
    "Xrotation": ("Xposition", "Yrotation", "Wrotation", "Xrotation Xrotation"),
    "Zrotation": ("Xrotation", "Zposition", "rotation"),
    "Xposition": ("Xrotation", "Yposition"),
    "begin": ("end", "BEGIN", "begin begin"),
    "end": ("begin", "END", "fin"),
    "name": ("names", "id"),
    "dof": ("dof rx rx", "dofs", "dof tx", "dof l"),
    "rx": ("rx rx", "tx", "ry", "l", "rw"),
    "axis": ("axis 0 0 0 XXZ", "axes", "axis 1 2"),
    "XYZ": ("XXZ", "ZYX", "xyz", "XY", "ABC", ""),
    "direction": ("direction 1e308 0 0", "length"),
    "length": ("length 1e-300", "direction", "length -1"),
    "order": ("order TX TX TZ RX RY RZ", "order RX RY RZ", "order", "order TX TY TZ RX RY RW"),
    "root": ("lfemur", "Root", "root root"),
    ":hierarchy": (":bonedata", ":root", ":HIERARCHY"),
    ":bonedata": (":hierarchy", ":bones"),
    ":units": (":root", ":unit"),
    "deg": ("rad", "grad"),
    ":DEGREES": (":RADIANS", ":DEGREE"),
}


@dataclass
class Case:
    kind: str  # 'bvh' | 'amc'
    motion: Path  # the .bvh or .amc
    asf: Path | None = None
    units: str | float = "auto"
    mutations: list[str] = field(default_factory=list)


def _first_frames_bvh(text: str, frames: int) -> list[str]:
    lines = text.split("\n")
    m = next(k for k, line in enumerate(lines) if line.strip() == "MOTION")
    lines[m + 1] = re.sub(r"\d+", str(frames), lines[m + 1], count=1)
    return lines[: m + 3 + frames]


def _first_frames_amc(text: str, frames: int) -> list[str]:
    lines = text.split("\n")
    starts = [k for k, line in enumerate(lines) if line.strip().isdigit()]
    return lines[: starts[frames]] if len(starts) > frames else lines


# Mutations: (rng, lines, kind) -> a description; they edit `lines` in place.


def _delete(rng, lines, kind):
    k = rng.randrange(len(lines))
    del lines[k]
    return f"delete line {k + 1}"


def _duplicate(rng, lines, kind):
    k = rng.randrange(len(lines))
    lines.insert(k, lines[k])
    return f"duplicate line {k + 1}"


def _swap(rng, lines, kind):
    a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
    lines[a], lines[b] = lines[b], lines[a]
    return f"swap lines {a + 1} and {b + 1}"


def _truncate(rng, lines, kind):
    k = rng.randrange(len(lines))
    cut = rng.randrange(len(lines[k]) + 1)
    lines[k] = lines[k][:cut]
    del lines[k + 1 :]
    return f"truncate at line {k + 1} column {cut}"


def _number(rng, lines, kind):
    hits = [(k, m) for k, line in enumerate(lines) for m in NUMBER.finditer(line)]
    if not hits:
        return "no number to replace"
    k, m = hits[rng.randrange(len(hits))]
    word = rng.choice(ODD_NUMBERS)
    lines[k] = lines[k][: m.start()] + word + lines[k][m.end() :]
    return f"number {m.group()!r} on line {k + 1} -> {word!r}"


def _garbage(rng, lines, kind):
    k = rng.randrange(len(lines))
    words = lines[k].split(" ")
    at = rng.randrange(len(words) + 1)
    token = rng.choice(GARBAGE)
    lines[k] = " ".join(words[:at] + [token] + words[at:])
    return f"insert {token!r} into line {k + 1}"


def _keyword(rng, lines, kind):
    hits = [
        (k, m)
        for k, line in enumerate(lines)
        for m in re.finditer(r"\S+", line)
        if m.group() in KEYWORDS
    ]
    if not hits:
        return "no keyword to change"
    k, m = hits[rng.randrange(len(hits))]
    word = rng.choice(KEYWORDS[m.group()])
    lines[k] = lines[k][: m.start()] + word + lines[k][m.end() :]
    return f"keyword {m.group()!r} on line {k + 1} -> {word!r}"


def _cut_brace(rng, lines, kind):
    hits = [k for k, line in enumerate(lines) if line.strip() in ("{", "}", "begin", "end")]
    if not hits:
        return "no brace to cut"
    k = rng.choice(hits)
    cut = lines.pop(k).strip()
    return f"cut {cut!r} at line {k + 1}"


def _deep(rng, lines, kind):
    """A chain of joints (bones) inserted under one: sane (50), at the limit, or absurd."""
    depth = rng.choice((50, 250, 400, 3000))
    if kind == "bvh":
        hits = [k for k, line in enumerate(lines) if line.strip().startswith("CHANNELS")]
        if not hits:
            return "no joint to nest under"
        k = rng.choice(hits)
        chain = [f"JOINT deep{n}\n{{\nOFFSET 0 0.1 0\nCHANNELS 0" for n in range(depth)]
        lines[k + 1 : k + 1] = ["\n".join(chain)] + ["}"] * depth
        return f"{depth} joints nested below line {k + 1}"
    bones = [
        f"  begin\n     name deep{n}\n     direction 0 1 0\n     length 0.1\n"
        f"     axis 0 0 0 XYZ\n  end"
        for n in range(depth)
    ]
    hierarchy = next((k for k, line in enumerate(lines) if line.startswith(":hierarchy")), None)
    top = next((k for k, line in enumerate(lines) if line.strip().startswith("root ")), None)
    if hierarchy is None or top is None:
        return "no hierarchy to nest in"
    edges = ["    root deep0"] + [f"    deep{n} deep{n + 1}" for n in range(depth - 1)]
    lines[top + 1 : top + 1] = edges
    lines[hierarchy:hierarchy] = bones
    return f"{depth} bones chained below root"


def _edge(rng, lines, kind):
    """A :hierarchy line giving some bone another parent, itself, or root as a child."""
    names = [line.split()[1] for line in lines if line.strip().startswith("name ")]
    end = next((k for k in range(len(lines) - 1, -1, -1) if lines[k].strip() == "end"), None)
    if not names or end is None:
        return "no hierarchy to add to"
    parent = rng.choice(names + ["root"])
    kid = rng.choice(names + ["root", parent])
    lines.insert(end, f"    {parent} {kid}")
    return f"hierarchy edge {parent} -> {kid}"


def _header(rng, lines, kind):
    """An odd frame count, frame time or length unit, or the header spelled with tabs."""
    if kind == "bvh":
        k = next((k for k, line in enumerate(lines) if line.strip() == "MOTION"), None)
        if k is None or k + 2 >= len(lines):
            return "no header"
        key = rng.choice(("Frames:", "Frame Time:", "Frame\tTime:", "Frame  Time:\t"))
        line = k + 1 if key == "Frames:" else k + 2
        value = rng.choice(ODD_NUMBERS + ("0.0333333", "0.001", "1", "1.0005", "0.00099"))
        lines[line] = f"{key} {value}"
        return f"line {line + 1} -> {lines[line]!r}"
    k = next((k for k, line in enumerate(lines) if line.strip().startswith("length ")), None)
    if k is None:
        return "no units length"
    lines[k] = f"  length {rng.choice(ODD_NUMBERS)}"
    return f"line {k + 1} -> {lines[k]!r}"


def _bytes(rng, lines, kind):
    k = rng.randrange(len(lines))
    at = rng.randrange(len(lines[k]) + 1)
    junk = rng.choice(("\r", "\x0b", "\x0c", "\x85", "\x00", "\ufeff", "\r\r\n"))
    lines[k] = lines[k][:at] + junk + lines[k][at:]
    return f"insert {junk!r} into line {k + 1}"


BVH_MUTATIONS = (
    _delete, _duplicate, _swap, _truncate, _number, _number, _number, _garbage, _keyword,
    _keyword, _cut_brace, _deep, _header, _header, _bytes,
)  # fmt: skip
ASF_MUTATIONS = BVH_MUTATIONS + (_edge, _edge)
AMC_MUTATIONS = (_delete, _duplicate, _swap, _truncate, _number, _number, _garbage, _bytes)


def _mutate(rng: random.Random, lines: list[str], kind: str, mutations) -> list[str]:
    done = []
    for _ in range(rng.choice((1, 1, 1, 2, 3))):
        if not lines:
            break
        done.append(rng.choice(mutations)(rng, lines, kind))
    return done


def _write(path: Path, lines: list[str]) -> None:
    path.write_bytes("\n".join(lines).encode("utf-8", "surrogatepass"))


def _make_cases(folder: Path) -> list[Case]:
    rng = random.Random(SEED)
    bvh = [(_first_frames_bvh(mocap(*p).read_text(), BVH_FRAMES), u) for p, u in BVH_SOURCES]
    amc = [
        (
            mocap(*a).read_bytes().decode(),
            _first_frames_amc(mocap(*m).read_bytes().decode(), AMC_FRAMES),
            Path(*m).name,
            Path(*a).name,
        )
        for a, m in AMC_SOURCES
    ]
    cases = []
    for n in range(N_FILES):
        case_dir = folder / f"c{n:03d}"
        case_dir.mkdir()
        if rng.random() < 0.5:
            lines, units = rng.choice(bvh)
            lines = list(lines)
            case = Case("bvh", case_dir / f"f{n:03d}.bvh", units=units)
            case.mutations = _mutate(rng, lines, "bvh", BVH_MUTATIONS)
            _write(case.motion, lines)
        else:
            asf_text, amc_lines, amc_name, asf_name = rng.choice(amc)
            asf_lines, amc_lines = asf_text.split("\n"), list(amc_lines)
            case = Case("amc", case_dir / amc_name, asf=case_dir / asf_name)
            which = rng.choice(("asf", "asf", "amc", "both"))
            if which in ("asf", "both"):
                case.mutations += [
                    "asf: " + m for m in _mutate(rng, asf_lines, "asf", ASF_MUTATIONS)
                ]
            if which in ("amc", "both"):
                case.mutations += [
                    "amc: " + m for m in _mutate(rng, amc_lines, "amc", AMC_MUTATIONS)
                ]
            _write(case.asf, asf_lines)
            _write(case.motion, amc_lines)
        cases.append(case)
    return cases


def _check_motion(m: Motion) -> None:
    """A Motion the database and the kinematics can take: finite, consistent shapes."""
    sk = m.skeleton
    n_joints = len(sk.joints)
    assert m.n_frames >= 1 and n_joints >= 1
    assert m.rotations.shape == (m.n_frames, n_joints, 4)
    assert np.all(np.isfinite(m.rotations))
    assert np.allclose(np.linalg.norm(m.rotations, axis=-1), 1.0, atol=1e-9)
    assert m.translations.shape == (m.n_frames, len(sk.translated), 3)
    assert np.all(np.abs(m.translations) <= MAX_LENGTH_M)
    assert FPS_RANGE[0] <= m.fps <= FPS_RANGE[1]
    assert len(set(sk.names)) == n_joints
    assert sk.joints[0].parent == -1
    assert all(0 <= j.parent < k for k, j in enumerate(sk.joints) if k)
    assert np.all(np.abs(sk.offsets) <= MAX_LENGTH_M)
    for j in sk.joints:
        assert j.end_site is None or np.all(np.abs(j.end_site) <= MAX_LENGTH_M)
        assert len(set(j.rotation_order)) == len(j.rotation_order) <= 3
    assert np.isfinite(sk.unit_m) and sk.unit_m > 0
    json.dumps(sk.hierarchy_json(), allow_nan=False)  # what the database stores
    json.dumps(m.meta, allow_nan=False)
    assert np.all(np.isfinite(m.world_positions()))


def _read(case: Case) -> Motion:
    if case.kind == "bvh":
        return read_bvh(str(case.motion), case.units)
    return read_amc(str(case.motion), read_asf(str(case.asf)))


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory):
    """The mutated files, each with what the parsers made of it: a Motion or the error."""
    cases = _make_cases(tmp_path_factory.mktemp("fuzz"))
    outcomes: list[Motion | MotionFileError] = []
    crashes = []
    for case in cases:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # e.g. numpy's overflow: a value went to inf
                outcome = _read(case)
            _check_motion(outcome)
        except MotionFileError as e:
            outcome = e
        except Exception as e:
            crashes.append(
                (
                    f"{case.motion} {case.mutations}: {type(e).__name__}: {str(e)[:200]}",
                    traceback.format_exc(),
                )
            )
            outcome = None
        outcomes.append(outcome)
    return cases, outcomes, crashes


def test_every_mutated_file_parses_or_is_refused_with_its_file(fuzzed):
    cases, outcomes, crashes = fuzzed
    assert not crashes, (
        f"{len(crashes)} of {len(cases)} files crashed a reader:\n"
        + "\n".join(what for what, _ in crashes)
        + "\n\nthe first:\n"
        + crashes[0][1]
    )
    refused = [e for e in outcomes if isinstance(e, MotionFileError)]
    for case, e in zip(cases, outcomes):
        if isinstance(e, MotionFileError):
            assert e.path in (str(case.motion), str(case.asf)), (e, case.mutations)
            assert str(e).startswith(e.path)
            assert e.line is None or 1 <= e.line, e
    # the mutations must reach both outcomes, or the test tests little
    assert len(cases) * 0.3 < len(refused) < len(cases) * 0.95, len(refused)


def test_keep_going_stores_exactly_the_files_it_reports_loaded(fuzzed, fresh_db, db, tmp_path):
    cases, outcomes, _ = fuzzed
    folder = tmp_path / "fuzz"
    picked = {}  # case folder name -> what the parsers made of its file
    quota = {True: N_LOADED // 2, False: N_LOADED - N_LOADED // 2}  # half of them parse
    # the mutations that once crashed a reader or reached the database first
    first = ("Frame", "length", "nested", "chained", "hierarchy edge", "1e", "5e")
    order = sorted(
        range(len(cases)), key=lambda k: not any(w in m for m in cases[k].mutations for w in first)
    )
    for case, outcome in ((cases[k], outcomes[k]) for k in order):
        parsed = isinstance(outcome, Motion)
        if case.units != "auto" or not quota[parsed]:  # CMU's BVH needs --units
            continue
        quota[parsed] -= 1
        target = folder / case.motion.parent.name
        target.mkdir(parents=True)
        for f in (case.motion, case.asf):
            if f is not None:
                (target / f.name).write_bytes(f.read_bytes())
        if isinstance(outcome, MotionFileError):  # the same words, about the copy
            outcome = str(outcome).replace(str(case.motion.parent), str(target))
        picked[target.name] = outcome
    r = run_modb(fresh_db, "load", folder, "--keep-going")
    assert "Traceback" not in r.stderr, r.stderr
    assert r.returncode in (0, 1), r.stderr
    summary = re.search(r"(\d+) files: (\d+) clip versions loaded .* (\d+) failed", r.stdout)
    assert summary, r.stdout
    files, loaded, n_failed = map(int, summary.groups())
    assert files == N_LOADED
    # every failure is listed with its file (an AMC's may name its ASF): its folder is its case
    listed = [line.strip() for line in r.stderr.splitlines() if line.startswith("  " + str(folder))]
    failed = {Path(line.split(":")[0]).parent.name for line in listed}
    assert len(failed) == n_failed == len(listed), r.stderr
    assert r.returncode == (1 if failed else 0)
    stored = {
        path.split("/")[-1]
        for (path,) in db.execute("SELECT modb.collection_path(collection_id) FROM modb.clips")
    }
    assert len(stored) == loaded == N_LOADED - n_failed
    assert stored == set(picked) - failed, r.stderr
    assert db.execute("SELECT count(*) FROM modb.clip_versions").fetchone()[0] == loaded
    # nothing left behind by a failure: no skeleton without a version, no empty collection
    orphans = db.execute(
        "SELECT count(*) FROM modb.skeletons s "
        "WHERE NOT EXISTS (SELECT 1 FROM modb.clip_versions v WHERE v.skeleton_id = s.id)"
    ).fetchone()[0]
    assert orphans == 0
    (collections,) = db.execute("SELECT count(*) FROM modb.collections").fetchone()
    assert collections == (loaded + 1 if loaded else 0)  # 'fuzz' and a 'fuzz/cNNN' per clip
    # what a parser refused, the command line refused in the same words
    for name, outcome in picked.items():
        if isinstance(outcome, str):
            assert outcome in listed, (outcome, r.stderr)
    # and what they accepted, the database took (a refusal there is a value a parser let through,
    # like the 0 fps that 'Frame Time: 3600' made)
    not_by_a_parser = [line for line in listed if not isinstance(picked[_case(line)], str)]
    assert not not_by_a_parser, "\n".join(not_by_a_parser)


def _case(line: str) -> str:
    return Path(line.split(":")[0]).parent.name
