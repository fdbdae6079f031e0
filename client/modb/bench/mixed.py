"""`modb bench mixed`: writers, psql readers and avatars at once against the real `modb serve`,
counted by the clients and held against the database (issue 39's mixed-concurrency run).

On a cluster of its own (a temporary MODB_HOME, removed after; or the database --dsn names), it
loads Bandai walks (collection mixed/walks) and one walk of another capture as a second skeleton,
builds a transition graph for the avatars, makes a loader token per writer and the edit scripts,
starts `modb serve`, and for the given seconds runs:
- writers (REST, modb.bench.mixed_clients.Writer): edit scripts applied to the same two clips (they
  collide), resamples to several frame rates (new frame-rate pools while snippets are built),
  retargets, annotation writes with If-Match, collection creates and moves, uploads;
- readers: pgbench, one connection each, the shipped select_next_snippet script;
- avatars: the web view's WebSocket, a goal clicked every 2 s.
Afterwards: audit rows per action against the writes the clients saw succeed, the clip versions
made against those the answers named, the collections made against the 201s; the server's and
PostgreSQL's logs for tracebacks and deadlocks. The verdict: no response >= 500, and every count
equal.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx
import psycopg
from psycopg.types.json import Jsonb

from modb.access import tokens as access_tokens
from modb.database.cluster import Cluster

from .commands import Commands
from .mixed_clients import APPLY, CHANGE, CREATE, META, RETARGET, UPLOAD, Ledger, Plan, Writer
from .mixed_clients import avatar_walk, read_loop

ROOT = "mixed"  # every collection the benchmark makes is under it
WALKS = f"{ROOT}/walks"
HOT_CLIPS = 2  # clips every writer edits
RESAMPLE_FPS = (24, 25, 48, 50, 60, 72, 90, 100)  # Bandai is 30 fps: each rate a new pool
SERVE_START_S = 60
DRIVER_TEXT = re.compile(r"\b(plpy|spiexceptions)\.")  # a message the server did not word
JOIN_GRACE_S = 150  # after the deadline: a write in flight may take this long (HTTP timeout 120)


@dataclass
class Check:
    what: str
    clients: int
    database: int

    @property
    def equal(self) -> bool:
        return self.clients == self.database


@dataclass
class Mixed:
    writers: int
    readers: int
    avatars: int
    seconds: float
    clips: int
    ledger: Ledger
    checks: list[Check]
    server_tracebacks: list[str]  # each traceback's last line: the exception
    postgres: Counter | None = None  # "deadlock detected", "ERROR"; None: a log not its own

    @property
    def server_errors(self) -> int:
        return sum(t.classes["5xx"] for t in self.ledger.tallies.values())

    @property
    def passed(self) -> bool:
        return self.server_errors == 0 and all(c.equal for c in self.checks)


def data_files(data: Path, clips: int) -> tuple[list[Path], Path]:
    """`clips` Bandai dataset 2 walks, straight ones first, then turns both ways (the avatars'
    graph needs them), and a dataset 1 walk (another skeleton) to retarget onto."""
    folder = data / "bandai-2-dev" / "data"
    kinds = [
        sorted(folder.glob(f"dataset-2_{kind}_active_*.bvh"))
        for kind in ("walk", "walk-turn-left", "walk-turn-right")
    ]
    share = -(-clips // len(kinds))
    walks = [f for files in kinds for f in files[:share]][:clips]
    other = sorted((data / "bandai-1" / "data").glob("dataset-1_walk_active_*.bvh"))[:1]
    if len(walks) < clips or not other:
        raise RuntimeError(
            f"{data} should hold bandai-2-dev/data with Bandai dataset 2's walks and turns "
            "(dataset-2_walk*_active_*.bvh) and bandai-1/data with a walk of dataset 1 "
            "(dataset-1_walk_active_*.bvh): name the mocap folder with --data"
        )
    return walks, other[0]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def serving(dsn: str, log: Path) -> Iterator[str]:
    """The real `modb serve` (writes on, as modb_web) on a free port; yields host:port."""
    port = _free_port()
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "modb.cli", "--dsn", dsn, "serve", "--port", str(port)],
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    address = f"127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + SERVE_START_S
        while True:
            try:
                if httpx.get(f"http://{address}/api/collections", timeout=5).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"modb serve did not start: {log.read_text()[-2000:]}")
            time.sleep(0.2)
        yield address
    finally:
        proc.terminate()
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _prepare(conn: psycopg.Connection, writers: int, run_id: str) -> dict:
    """Scripts, collections and tokens the writers use (before the counted run, not audited)."""
    conn.execute(
        "INSERT INTO modb.edit_scripts (name, commands, comment) VALUES (%s, %s, %s) "
        "ON CONFLICT (name) DO UPDATE SET commands = EXCLUDED.commands",
        ["mixed-smooth", Jsonb([{"op": "smooth", "seconds": 0.02}]), "modb bench mixed"],
    )
    for fps in RESAMPLE_FPS:
        conn.execute(
            "INSERT INTO modb.edit_scripts (name, commands, comment) VALUES (%s, %s, %s) "
            "ON CONFLICT (name) DO UPDATE SET commands = EXCLUDED.commands",
            [f"mixed-resample-{fps}", Jsonb([{"op": "resample", "fps": fps}]), "modb bench mixed"],
        )
    for path in ("retargets", "uploads", "moved", "made"):
        conn.execute("SELECT modb.ensure_collection(%s)", [f"{ROOT}/{path}"])
    clips = [
        r[0]
        for r in conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = %s ORDER BY clip_id",
            [WALKS],
        )
    ]
    (skeleton,) = conn.execute(
        "SELECT skeleton_id FROM modb.current_clips WHERE collection = %s LIMIT 1",
        [f"{ROOT}/target"],
    ).fetchone()
    low, high = conn.execute("SELECT min(id), max(id) FROM modb.snippets").fetchone()
    names = [f"bench-mixed-{run_id}-w{i}" for i in range(writers)]
    return {
        "clips": clips,
        "skeleton": skeleton,
        "snippets": (low, high),
        "tokens": [access_tokens.create(conn, name, "loader") for name in names],
        "token_prefix": f"bench-mixed-{run_id}-",
    }


def _snapshot(conn: psycopg.Connection) -> dict:
    return {
        "audit": conn.execute("SELECT coalesce(max(id), 0) FROM modb.audit_log").fetchone()[0],
        "versions": set(conn.execute("SELECT clip_id, version FROM modb.clip_versions")),
        "collections": conn.execute("SELECT count(*) FROM modb.collections").fetchone()[0],
    }


def _checks(conn: psycopg.Connection, before: dict, ledger: Ledger, prefix: str) -> list[Check]:
    audited = Counter(
        dict(
            conn.execute(
                "SELECT action, count(*) FROM modb.audit_log WHERE id > %s AND "
                "starts_with(token_name, %s) GROUP BY action",
                [before["audit"], prefix],
            ).fetchall()
        )
    )
    after = _snapshot(conn)
    made = after["versions"] - before["versions"]
    answered = ledger.versions - before["versions"]  # a retarget again names an older version
    checks = [
        Check(f"audit rows '{action}'", ledger.audited[action], audited[action])
        for action in (APPLY, RETARGET, META, CREATE, CHANGE, UPLOAD)
    ]
    checks += [
        Check(f"audit rows '{a}' (no client saw it succeed)", 0, n)
        for a, n in audited.items()
        if a not in (APPLY, RETARGET, META, CREATE, CHANGE, UPLOAD)
    ]
    checks += [
        Check("clip versions made", len(answered), len(made)),
        Check(
            "clip versions the answers name and the database has",
            len(answered),
            len(answered & made),
        ),  # fmt: skip
        Check(
            "collections made (201)",
            ledger.collections_made,
            after["collections"] - before["collections"],
        ),  # fmt: skip
    ]
    return checks


def _postgres_log(log: Path | None, offset: int) -> Counter | None:
    if log is None or not log.exists():
        return None
    found: Counter = Counter()
    with open(log, errors="replace") as f:
        f.seek(offset)
        for line in f:
            if "deadlock detected" in line:
                found["deadlock detected"] += 1
            if "ERROR:" in line:
                found["ERROR"] += 1
    return found


def _run_clients(
    dsn: str, plan: Plan, readers: int, avatars: int, seconds: float, snippets, ledger: Ledger
) -> None:
    until = time.monotonic() + seconds
    threads = [
        threading.Thread(target=Writer(i, plan, ledger).run, args=(until,), daemon=True)
        for i in range(len(plan.tokens))
    ]
    threads += [
        threading.Thread(target=read_loop, args=(dsn, *snippets, until, ledger), daemon=True)
        for _ in range(readers)
    ]
    threads += [
        threading.Thread(
            target=avatar_walk, args=(plan.address, i, plan.seed, until, ledger), daemon=True
        )
        for i in range(avatars)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=max(0.0, until + JOIN_GRACE_S - time.monotonic()))
    if any(t.is_alive() for t in threads):
        raise RuntimeError(f"a client was still running {JOIN_GRACE_S} s after the deadline")


def run(
    data: Path,
    writers: int,
    readers: int,
    avatars: int,
    seconds: float,
    say: Callable[[str], None],
    commands: Commands,
    dsn: str | None = None,
    clips: int = 12,
    seed: int = 1,
    postgres_log: Path | None = None,
) -> Mixed:
    """The benchmark on `dsn` (None: a fresh cluster of its own, removed after); `postgres_log`:
    that server's log, read for errors and deadlocks (its own cluster's is read anyway)."""
    walks, other = data_files(data, clips)
    home = None
    cluster = None
    try:
        if dsn is None:
            home = Path(tempfile.mkdtemp(prefix="modb-mixed-"))
            if os.geteuid() == 0:
                shutil.chown(home, "postgres", "postgres")
            cluster = Cluster(home)
            cluster.start()  # with the writer role modb_web
            dsn = cluster.dsn()
            say(f"a cluster of its own in {home}")
        say(f"loading {len(walks)} walks and a second skeleton from {data}")
        if commands.load(dsn, [str(f) for f in walks], WALKS) != 0:
            raise RuntimeError(f"modb load {walks[0]} ... failed (its message is above)")
        if commands.load(dsn, [str(other)], f"{ROOT}/target") != 0:
            raise RuntimeError(f"modb load {other} failed (its message is above)")
        if avatars and commands.build_graph(dsn, "mixed", WALKS) != 0:
            raise RuntimeError("modb graph build failed (its message is above)")
        run_id = f"{os.getpid()}-{int(time.time())}"
        with psycopg.connect(dsn, autocommit=True) as conn:
            prepared = _prepare(conn, writers, run_id)
        if cluster is not None:
            postgres_log = cluster.logfile
        log_offset = postgres_log.stat().st_size if postgres_log and postgres_log.exists() else 0
        ledger = Ledger()
        with tempfile.TemporaryDirectory(prefix="modb-mixed-serve-") as tmp:
            serve_log = Path(tmp) / "serve.log"
            with serving(dsn, serve_log) as address:
                plan = Plan(
                    address,
                    prepared["tokens"],
                    prepared["clips"][:HOT_CLIPS],
                    prepared["clips"][HOT_CLIPS:],
                    prepared["skeleton"],
                    walks[-1],
                    "mixed-smooth",
                    [f"mixed-resample-{fps}" for fps in RESAMPLE_FPS],
                    ROOT,
                    seed,
                )
                with psycopg.connect(dsn, autocommit=True) as conn:
                    before = _snapshot(conn)
                say(f"{writers} writers, {readers} readers, {avatars} avatars for {seconds:g} s")
                _run_clients(dsn, plan, readers, avatars, seconds, prepared["snippets"], ledger)
            tracebacks = _exceptions(serve_log.read_text(errors="replace"))
        with psycopg.connect(dsn, autocommit=True) as conn:
            checks = _checks(conn, before, ledger, prepared["token_prefix"])
        return Mixed(
            writers,
            readers,
            avatars,
            seconds,
            len(walks),
            ledger,
            checks,
            tracebacks,
            _postgres_log(postgres_log, log_offset),
        )
    finally:
        if cluster is not None:
            cluster.stop()
        if home is not None:
            shutil.rmtree(home, ignore_errors=True)


def _exceptions(log: str) -> list[str]:
    """The exception each traceback in a log ends with (the first unindented line after it)."""
    found = []
    for block in log.split("Traceback (most recent call last):")[1:]:
        lines = block.splitlines()[1:]
        found.append(next((x for x in lines if x and not x.startswith(" ")), "?")[:200])
    return found


def report(m: Mixed) -> str:
    lines = [
        f"{m.writers} writers (REST), {m.readers} readers (pgbench, select_next_snippet), "
        f"{m.avatars} avatars (WebSocket), {m.seconds:g} s, on {m.clips} Bandai walks",
        "",
        "| client | request | sent | 2xx/ok | 4xx | 5xx | errors (no answer) |",
        "|---|---|---|---|---|---|---|",
    ]
    for (kind, action), t in sorted(m.ledger.tallies.items()):
        ok = t.classes["2xx"] + t.classes["ok"]
        lines.append(
            f"| {kind} | {action} | {t.requests} | {ok} | {t.classes['4xx']} | "
            f"{t.classes['5xx']} | {t.errors} |"
        )
    if m.ledger.extra:
        lines += ["", ", ".join(f"{k}: {v}" for k, v in sorted(m.ledger.extra.items()))]
    lines += ["", "| check | clients | database | equal |", "|---|---|---|---|"]
    lines += [
        f"| {c.what} | {c.clients} | {c.database} | {'yes' if c.equal else 'NO'} |"
        for c in m.checks
    ]
    postgres = (
        f"{m.postgres['ERROR']} ERROR lines, {m.postgres['deadlock detected']} deadlocks"
        if m.postgres is not None
        else "not read (not the benchmark's own cluster: --postgres-log names it)"
    )
    lines += [
        "",
        f"modb serve's log: {len(m.server_tracebacks)} tracebacks; PostgreSQL's log: {postgres}",
    ]
    lines += [f"  {n} x {e}" for e, n in Counter(m.server_tracebacks).most_common()]
    answers = Counter()
    for (kind, action), t in m.ledger.tallies.items():
        for (status, message), n in t.messages.items():
            answers[(kind, action, status, message)] += n
    if answers:
        lines += ["", "answers other than 2xx, most frequent first:"]
        lines += [
            f"  {n} x {kind} {action} {status}: {message}"
            for (kind, action, status, message), n in answers.most_common(15)
        ]
    raw = sum(n for (_, _, _, message), n in answers.items() if DRIVER_TEXT.search(message))
    if raw:
        lines += [
            "",
            f"also: {raw} answers carry the database driver's text (plpy./spiexceptions.) "
            "instead of a message of their own",
        ]
    unequal = [c.what for c in m.checks if not c.equal]
    lines += [
        "",
        f"verdict: {'PASS' if m.passed else 'FAIL'}: responses >= 500: {m.server_errors}"
        f" ({'none' if not m.server_errors else 'want none'}); counts "
        + ("all equal" if not unequal else f"unequal: {', '.join(unequal)}"),
    ]
    return "\n".join(lines)
