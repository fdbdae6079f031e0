"""`modb bench first-call`: what the first call of a PL/Python-backed function costs a new session,
with the kernel pasted into every function body (0.23.0) and installed once per version as a
compiled package the functions import (0.24.0, the default).

Until 0.23.0 each such function carried the whole kernel (~200 KB of source), so a session's first
call compiled and ran all of it; from 0.24.0 the first call imports the .pyc of the modules it
names. Both versions are measured in the same run, on the same data, alternately, so the ratio
holds on a noisy machine: database A is created at 0.23.0 (a few Bandai walks, their steps, the
step models and their graph), B is a copy of A updated to the default version.

Per round, for each function and each version (in a shuffled order), a new psycopg connection with
the default session settings, and the client's wall clock around the first call (execute and
fetch; the connection not counted). The breakdown, in another new session: a DO block timing
`import numpy` and the scipy submodules the kernel imports, then the function's first call (the
kernel's import and the work: numpy is loaded) and its second call (the work): the kernel's own
cost is the difference. A first, untimed round warms the file cache.
"""

from __future__ import annotations

import random
import re
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import psycopg

from modb.database.cluster import Cluster
from modb.version import CONTROL

from .commands import Commands

BEFORE = "0.23.0"  # the last version with the kernel pasted into every function
DATABASES = ("modb_bench_first_call_before", "modb_bench_first_call_after")
WALKS = "dataset-2_walk_active_00[1-6].bvh"
COLLECTION = "first call"
GRAPH = "steps"
FRAMES = 4  # forward_kinematics' frames

CALLS = {
    "forward_kinematics": "SELECT * FROM modb.forward_kinematics(%s::jsonb, %s::real[], "
    "%s::real[])",
    "sample_motion": "SELECT * FROM modb.sample_motion('left steps', 1, %s)",
    "synthesize_from_models": f"SELECT * FROM modb.synthesize_from_models('{GRAPH}', "
    "ARRAY[[0, 3]]::float8[], 2)",
}
CLIP = f"""SELECT s.hierarchy::text, v.rotations[1:{FRAMES}]::text, v.translations[1:{FRAMES}]::text
  FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
 ORDER BY v.clip_id, v.version LIMIT 1"""
# numpy, then every scipy submodule the kernel imports (each inside the function that needs it).
IMPORTS = """DO LANGUAGE plpython3u $py$
import time
t = time.perf_counter()
import numpy
t1 = time.perf_counter()
import scipy.interpolate, scipy.optimize, scipy.sparse.csgraph, scipy.spatial
plpy.notice("modb-first-call numpy %.6f scipy %.6f" % (t1 - t, time.perf_counter() - t1))
$py$"""
IMPORTED = re.compile(r"modb-first-call numpy (\S+) scipy (\S+)")


@dataclass
class Breakdown:
    """One session's seconds: the DO block's rest (PL/Python's start), numpy's import, scipy's, the
    function's first call after them, its second call."""

    start: float
    numpy: float
    scipy: float
    first: float
    second: float


@dataclass
class Figures:
    """One function on one version: every round's first call, and every round's breakdown."""

    first: list[float] = field(default_factory=list)
    breakdown: list[Breakdown] = field(default_factory=list)


@dataclass
class Result:
    rounds: int
    versions: tuple[str, str]  # before, after
    figures: dict[tuple[str, str], Figures]  # (function, version)
    script_kb: list[tuple[str, float]]


def databases(folder: Path, commands: Commands, say: Callable[[str], None]) -> dict[str, str]:
    """{version: dsn} of A (0.23.0, filled) and B (A's copy updated to the default version)."""
    files = sorted(str(f) for f in folder.glob(WALKS))
    if not files:
        raise RuntimeError(f"no Bandai dataset 2 walks ({WALKS}) in {folder}")
    cluster = Cluster.default()
    cluster.start()
    before, after = (cluster.dsn(name) for name in DATABASES)
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        for name in DATABASES:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{DATABASES[0]}"')
    with psycopg.connect(before, autocommit=True) as conn:
        conn.execute(f"CREATE EXTENSION modb VERSION '{BEFORE}' CASCADE")
    say(f"{BEFORE}: {len(files)} walks, their steps, the step models and their graph")
    steps = [
        lambda: commands.load(before, files, COLLECTION),
        lambda: commands.annotate_steps(before, COLLECTION),
        lambda: commands.build_model(before, "left steps", COLLECTION, "left_step"),
        lambda: commands.build_model(before, "right steps", COLLECTION, "right_step"),
        lambda: commands.build_model_graph(before, GRAPH, COLLECTION),
    ]
    for step in steps:
        if step() != 0:
            raise RuntimeError(f"filling the {BEFORE} database from {folder} failed")
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{DATABASES[1]}" TEMPLATE "{DATABASES[0]}"')
    with psycopg.connect(after, autocommit=True) as conn:
        conn.execute("ALTER EXTENSION modb UPDATE")
        (version,) = conn.execute(
            "SELECT extversion FROM pg_extension WHERE extname = 'modb'"
        ).fetchone()
    if version == BEFORE:
        raise RuntimeError(f"the default version of modb is {BEFORE}: nothing to compare it with")
    return {BEFORE: before, version: after}


def _timed(conn: psycopg.Connection, sql: str, params: Sequence[object]) -> float:
    t = time.perf_counter()
    conn.execute(sql, params).fetchall()
    return time.perf_counter() - t


def first_call(dsn: str, sql: str, params: Sequence[object]) -> float:
    """Seconds of the first statement of a new session."""
    with psycopg.connect(dsn) as conn:
        return _timed(conn, sql, params)


def breakdown(dsn: str, sql: str, params: Sequence[object]) -> Breakdown:
    """A new session: the imports' DO block, then the call twice."""
    with psycopg.connect(dsn) as conn:
        said: list[str] = []
        conn.add_notice_handler(lambda d: said.append(d.message_primary or ""))
        t = time.perf_counter()
        conn.execute(IMPORTS)
        block = time.perf_counter() - t
        found = [m for s in said if (m := IMPORTED.match(s))]
        if not found:
            raise RuntimeError(f"the imports' DO block said nothing of their times: {said}")
        numpy_s, scipy_s = (float(g) for g in found[0].groups())
        first = _timed(conn, sql, params)
        second = _timed(conn, sql, params)
        return Breakdown(block - numpy_s - scipy_s, numpy_s, scipy_s, first, second)


def script_sizes() -> list[tuple[str, float]]:
    """The install and upgrade scripts of 0.23.0 and 0.24.0 (released, else as built), in KB."""
    extension = CONTROL.parent
    names = ["modb--0.23.0.sql", "modb--0.22.0--0.23.0.sql", "modb--0.24.0.sql",
             "modb--0.23.0--0.24.0.sql"]  # fmt: skip
    out = []
    for name in names:
        path = extension / "sql" / "released" / name
        path = path if path.exists() else extension / name
        if path.exists():
            out.append((str(path.relative_to(extension.parent)), path.stat().st_size / 1024))
    return out


def _params(function: str, clip: Sequence[object], round_: int) -> list[object]:
    """forward_kinematics: the first loaded clip's skeleton and first frames; sample_motion: the
    round as the seed."""
    return {"forward_kinematics": list(clip), "sample_motion": [round_]}.get(function, [])


def run(folder: Path, rounds: int, commands: Commands, say: Callable[[str], None]) -> Result:
    """The two databases made, then `rounds` rounds (and one untimed first) of every function on
    both versions; `say` gets the progress."""
    dsns = databases(folder, commands, say)
    with psycopg.connect(dsns[BEFORE]) as conn:
        clip = conn.execute(CLIP).fetchone()
    if clip is None:
        raise RuntimeError("no clip was loaded")
    versions = tuple(dsns)
    figures = {(f, v): Figures() for f in CALLS for v in versions}
    shuffle = random.Random(0).shuffle
    for r in range(rounds + 1):  # round 0: untimed, warms the file cache
        say(f"round {r} of {rounds}" + (" (warm-up)" if r == 0 else ""))
        for function, sql in CALLS.items():
            params = _params(function, clip, r)
            order = list(versions)
            shuffle(order)
            for version in order:
                seconds = first_call(dsns[version], sql, params)
                parts = breakdown(dsns[version], sql, params)
                if r:
                    figures[function, version].first.append(seconds)
                    figures[function, version].breakdown.append(parts)
    return Result(rounds, (versions[0], versions[1]), figures, script_sizes())


def _ms(seconds: float) -> str:
    return f"{1000 * seconds:.1f}"


def report(result: Result) -> str:
    before, after = result.versions
    lines = [
        f"First call of a new session (client wall clock, connection excluded), {result.rounds} "
        "rounds, ms:",
        "",
        f"| function | {before} median | {before} p99 | {after} median | {after} p99 | "
        "after/before median | after/before p99 |",
        "|---|---|---|---|---|---|---|",
    ]
    for function in CALLS:
        a, b = result.figures[function, before].first, result.figures[function, after].first
        pa, pb = float(np.percentile(a, 99)), float(np.percentile(b, 99))
        ma, mb = statistics.median(a), statistics.median(b)
        lines.append(f"| {function} | {_ms(ma)} | {_ms(pa)} | {_ms(mb)} | {_ms(pb)} | "
                     f"{mb / ma:.2f} | {pb / pa:.2f} |")  # fmt: skip
    lines += [
        "",
        "Breakdown, another new session each (medians, ms): a DO block's rest (PL/Python's start), "
        "its imports",
        "of numpy and scipy; then the function's first call (kernel + work) and second call "
        "(work); kernel = first - second.",
        "",
        "| function | version | PL/Python start | numpy | scipy | first call | second call "
        "| kernel |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for function in CALLS:
        for version in result.versions:
            parts = result.figures[function, version].breakdown

            def median(of: Callable[[Breakdown], float], parts: list[Breakdown] = parts) -> str:
                return _ms(statistics.median(of(p) for p in parts))

            lines.append(
                f"| {function} | {version} | {median(lambda p: p.start)} | "
                f"{median(lambda p: p.numpy)} | {median(lambda p: p.scipy)} | "
                f"{median(lambda p: p.first)} | {median(lambda p: p.second)} | "
                f"{median(lambda p: p.first - p.second)} |"
            )
    lines += ["", "| script | KB |", "|---|---|"]
    lines += [f"| {name} | {kb:,.0f} |" for name, kb in result.script_kb]
    return "\n".join(lines)
