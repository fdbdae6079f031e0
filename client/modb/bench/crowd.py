"""`modb bench crowd`: N simulated avatars against a primary and k hot standbys of a cluster of the
benchmark's own, on this machine, and what k machines would serve.

Each avatar is the real Avatar (the web view's), played at its source rate on a node chosen as
`modb serve` chooses (modb.database.read_nodes), walking a seeded course; it chooses a snippet
about every 0.5 s. Halfway, more clips are loaded on the primary (a writer's load while the crowd
walks). Measured per node: choices per second, query latency p50/p99, stalls (a choice that came
later than its snippet was due), and, from /proc, the CPU seconds its client backends spent (per
selection) and its startup process spent replaying; and the primary's WAL written per second of
loading. The model for k machines of this kind uses those figures (see model()).
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import psycopg

from modb.database.cluster import Cluster
from modb.database.read_nodes import ReadNodes
from modb.database.replicas import Replicas
from modb.synthesis.avatar import Avatar, Settings

from .commands import Commands
from .synth import seeded_course

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
LEAD_TIME_S = 0.25  # the avatar's default in the web view is 0; a crowd hides latency
REPLAY_TIMEOUT_S = 300  # a standby that has not replayed the halfway load by then has failed


@dataclass
class NodeFigures:
    name: str
    avatars: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    stalls: int = 0
    cpu_choices: int = 0  # choices while CPU was counted (after the warm-up)
    backend_cpu_s: float = 0.0
    replay_cpu_s: float = 0.0

    @property
    def choices(self) -> int:
        return len(self.latencies_ms)


@dataclass
class Crowd:
    avatars: int
    standbys: int
    seconds: float
    nodes: dict[str, NodeFigures]
    round_trip_ms: float  # SELECT 1 over this machine's socket, median
    wal_bytes_per_load_s: float  # the primary's WAL while loading
    walsender_cpu_share: float  # of a core, per standby, the primary's sending while loading
    load_seconds: float
    failures: list[str]
    client_cpu_s_per_avatar_s: float  # this process (the avatars' frames), per avatar-second
    cores: int = field(default_factory=lambda: os.cpu_count() or 1)


def _cpu_seconds(pids: list[int]) -> float:
    total = 0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # ended
        total += int(fields[11]) + int(fields[12])  # utime, stime
    return total / CLOCK_TICKS


def _pids(dsn: str, backend_type: str) -> list[int]:
    with psycopg.connect(dsn, autocommit=True) as conn:
        return [
            r[0]
            for r in conn.execute(
                "SELECT pid FROM pg_stat_activity WHERE backend_type = %s AND pid <> "
                "pg_backend_pid()",
                [backend_type],
            )
        ]


def _walk(
    avatar: Avatar, until: float, figures: Callable[[], NodeFigures], failures: list[str]
) -> None:
    """Plays the avatar's frames at their rate until `until`; each choice counted on its node.
    Its connection stays open (run() closes it once its backend's CPU time is read)."""
    due = time.monotonic()
    seen = 0
    try:
        for _frame in avatar.frames():
            if len(avatar.choices) > seen:
                seen = len(avatar.choices)
                choice = avatar.choices[-1]
                f = figures()
                if choice.latency_ms is not None and choice.step > 0:  # not the cold start
                    f.latencies_ms.append(choice.latency_ms)
                if choice.waited_ms > 1000.0 / choice.fps:
                    f.stalls += 1
                frame_s = 1.0 / choice.fps
            now = time.monotonic()
            if now >= until:
                return
            due = max(due + frame_s, now)
            time.sleep(max(0.0, due - now))
    except Exception as e:  # counted, not hidden: the report lists them
        failures.append(f"{type(e).__name__}: {e}")


def _load_and_replay(
    primary: str,
    standbys: list[str],
    startup: dict[str, list[int]],
    files: list[Path],
    out: dict[str, float],
) -> None:
    """Loads `files` on the primary and waits until every standby has replayed the load; out: its
    seconds, its WAL bytes, each standby's replay CPU seconds over that time, and the primary's
    walsenders' CPU seconds ("sending")."""
    replay_before = {k: _cpu_seconds(p) for k, p in startup.items()}
    senders = _pids(primary, "walsender")
    sending_before = _cpu_seconds(senders)
    with psycopg.connect(primary, autocommit=True) as conn:
        lsn = conn.execute("SELECT pg_current_wal_lsn()").fetchone()[0]
        t = time.monotonic()
        # another process, as a writer would be: this one's CPU is the avatars'
        subprocess.run(
            [
                sys.executable,
                "-m",
                "modb.cli",
                "--dsn",
                primary,
                "load",
                *map(str, files),
                "--collection",
                "crowd more",
                "-q",
            ],  # fmt: skip
            check=True,
        )
        out["seconds"] = time.monotonic() - t
        end, out["wal"] = conn.execute(
            "SELECT pg_current_wal_lsn(), pg_wal_lsn_diff(pg_current_wal_lsn(), %s)", [lsn]
        ).fetchone()
    deadline = time.monotonic() + REPLAY_TIMEOUT_S
    for dsn in standbys:
        with psycopg.connect(dsn, autocommit=True) as conn:
            while conn.execute("SELECT pg_last_wal_replay_lsn() < %s::pg_lsn", [end]).fetchone()[0]:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"{dsn} did not replay the load in {REPLAY_TIMEOUT_S} s")
                time.sleep(0.05)
    out["sending"] = _cpu_seconds(senders) - sending_before
    for k, p in startup.items():
        out[f"replay {k}"] = _cpu_seconds(p) - replay_before[k]


def _load_and_replay_noting_errors(*args) -> None:
    try:
        _load_and_replay(*args)
    except Exception as e:  # the main thread raises it
        args[-1]["error"] = f"{type(e).__name__}: {e}"


def run(
    data: Path,
    avatars: int,
    standbys: int,
    seconds: float,
    say: Callable[[str], None],
    commands: Commands,
) -> Crowd:
    """The benchmark on a fresh cluster in a temporary MODB_HOME (removed after), with Bandai
    dataset 2's active walks and turns from `data` (its runs loaded halfway); `commands` loads
    them and builds the graph."""
    first = sorted(data.glob("dataset-2_walk*_active_*.bvh"))
    more = sorted(data.glob("dataset-2_run_active_*.bvh"))
    if not first or not more:
        raise RuntimeError(f"no Bandai dataset 2 active walks and runs in {data}")

    home = Path(tempfile.mkdtemp(prefix="modb-crowd-"))
    if os.geteuid() == 0:
        shutil.chown(home, "postgres", "postgres")
    primary = Cluster(home)
    replicas = Replicas(primary)
    try:
        primary.start()
        dsn = primary.dsn()
        say(f"loading {data} into a cluster of its own ({home})")
        if commands.load(dsn, [str(f) for f in first], "crowd") != 0:
            raise RuntimeError(f"modb load {first[0]} failed (its message is above)")
        if commands.build_graph(dsn, "crowd", "crowd") != 0:
            raise RuntimeError("modb graph build failed (its message is above)")
        names = [f"s{i + 1}" for i in range(standbys)]
        for name in names:
            say(f"standby {name}")
            replicas.add(name)
        nodes = ReadNodes(dsn, [(n, replicas.get(n).node.dsn()) for n in names])
        figures = {n.name: NodeFigures(n.name) for n in [*nodes.standbys, nodes.primary]}
        with psycopg.connect(dsn, autocommit=True) as conn:
            round_trip = []
            for _ in range(200):
                t = time.perf_counter()
                conn.execute("SELECT 1").fetchone()
                round_trip.append((time.perf_counter() - t) * 1000.0)
        say(f"{avatars} avatars for {seconds:g} s")
        start = time.monotonic()
        until = start + seconds
        failures: list[str] = []
        threads, walking = [], []
        for i in range(avatars):
            node, conn = nodes.open()
            figures[node.name].avatars += 1
            avatar = Avatar(
                conn,
                goals=seeded_course(i + 1, n_goals=int(seconds // 5) + 2),
                settings=replace(Settings(), lead_time=LEAD_TIME_S, collection="crowd"),
            )
            walking.append(avatar)
            threads.append(
                threading.Thread(
                    target=_walk,
                    args=(avatar, until, lambda name=node.name: figures[name], failures),
                    daemon=True,
                )
            )
        for t in threads:
            t.start()
        time.sleep(min(5.0, seconds / 4))  # connected and warmed: CPU counted from here
        counted = {n.name: (n.dsn, _pids(n.dsn, "client backend")) for n in nodes.standbys}
        counted["primary"] = (dsn, _pids(dsn, "client backend"))
        startup = {n.name: _pids(n.dsn, "startup") for n in nodes.standbys}
        before = {k: _cpu_seconds(p) for k, (_, p) in counted.items()}
        client_before, client_from = sum(os.times()[:2]), time.monotonic()
        first_choices = {k: f.choices for k, f in figures.items()}
        time.sleep(max(0.0, (until - time.monotonic()) / 2))
        loading: dict[str, float] = {}
        loader = threading.Thread(
            target=_load_and_replay_noting_errors,
            args=(dsn, [n.dsn for n in nodes.standbys], startup, more, loading),
        )
        loader.start()
        # CPU is read while every avatar's backend is there (their connections close after)
        time.sleep(max(0.0, until - 0.5 - time.monotonic()))
        for k, (_, p) in counted.items():
            figures[k].backend_cpu_s = _cpu_seconds(p) - before[k]
        for k, f in figures.items():
            f.cpu_choices = f.choices - first_choices[k]
        client_cpu = (sum(os.times()[:2]) - client_before) / (
            avatars * (time.monotonic() - client_from)
        )
        loader.join()
        for t, avatar in zip(threads, walking):
            t.join(timeout=30)
            if not t.is_alive():  # one still walking has its connection closed by the server
                avatar.conn.close()
        if "error" in loading:
            raise RuntimeError(f"the load during the walk failed: {loading['error']}")
        for k in startup:
            figures[k].replay_cpu_s = loading.get(f"replay {k}", 0.0)
        load_seconds = loading["seconds"]
        return Crowd(
            avatars,
            standbys,
            seconds,
            figures,
            statistics.median(round_trip),
            float(loading["wal"]) / max(load_seconds, 1e-9),
            loading["sending"] / max(load_seconds, 1e-9) / max(standbys, 1),
            load_seconds,
            failures,
            client_cpu,
        )
    finally:
        for name in [r.name for r in replicas.all()]:
            replicas.get(name).node.stop()
        primary.stop()
        shutil.rmtree(home, ignore_errors=True)


def model(crowd: Crowd, machines: int) -> dict[str, float]:
    """What `machines` standbys of this kind would serve, from the measured figures: each machine's
    cores spend the CPU per selection measured here (all standbys' backends over their choices)
    plus the replay CPU measured per second of the primary's loading (assumed loading all the
    time: the worst case); an avatar asks one selection per 0.5 s; latency = this machine's p50
    plus a network round trip (measured here over a unix socket; a LAN adds about 0.2 ms). What
    does not scale: the primary sends its WAL once per standby, so its sending CPU (measured per
    standby) and its outgoing bytes grow with `machines`; `primary_sending_share` is that CPU, in
    cores, while it loads."""
    standby = [f for f in crowd.nodes.values() if f.name != "primary"]
    choices = sum(f.cpu_choices for f in standby)
    cpu = sum(f.backend_cpu_s for f in standby)
    cpu_per_choice = cpu / choices if choices else float("nan")
    replay_share = max(f.replay_cpu_s for f in standby) / crowd.load_seconds if standby else 0.0
    per_machine = max(0.0, crowd.cores - replay_share) / cpu_per_choice
    latencies = [v for f in standby for v in f.latencies_ms]
    return {
        "cpu_ms_per_choice": 1000.0 * cpu_per_choice,
        "replay_cpu_share": replay_share,
        "choices_per_s_per_machine": per_machine,
        "avatars": machines * per_machine * 0.5,
        "latency_p50_ms": (float(np.percentile(latencies, 50)) if latencies else float("nan"))
        + crowd.round_trip_ms,
        "primary_sending_share": machines * crowd.walsender_cpu_share,
        "primary_wal_out_mb_per_s": machines * crowd.wal_bytes_per_load_s / 2**20,
    }


def against(crowd: Crowd, baseline: Crowd) -> str:
    """The standbys' latency (all their choices together) and stalls over the primary alone's."""
    served = np.array([v for f in crowd.nodes.values() for v in f.latencies_ms])
    alone = np.array(baseline.nodes["primary"].latencies_ms)
    if not served.size or not alone.size:
        return "no ratio: a run made no choices"
    p50, b50 = np.percentile(served, 50), np.percentile(alone, 50)
    p99, b99 = np.percentile(served, 99), np.percentile(alone, 99)
    stalls = sum(f.stalls for f in crowd.nodes.values())
    return (
        f"{crowd.standbys} standbys against the primary alone (same avatars, same process): "
        f"p50 {p50:.1f} ms / {b50:.1f} ms = {p50 / b50:.2f}x, p99 {p99:.1f} ms / {b99:.1f} ms = "
        f"{p99 / b99:.2f}x, stalls {stalls} / {baseline.nodes['primary'].stalls}"
    )


def report(crowd: Crowd) -> str:
    lines = [
        f"{crowd.avatars} avatars, {crowd.standbys} standbys, {crowd.seconds:g} s, "
        f"{crowd.cores} cores; a load on the primary halfway ({crowd.load_seconds:.1f} s, "
        f"{crowd.wal_bytes_per_load_s / 2**20:.1f} MB of WAL per second)",
        "",
        "| node | avatars | choices/s | latency p50 | p99 | stalls | CPU ms per choice | "
        "replay CPU s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for f in crowd.nodes.values():
        if not f.avatars and f.name == "primary" and crowd.standbys:
            continue
        lat = np.array(f.latencies_ms) if f.latencies_ms else np.array([np.nan])
        cpu_choices = f.cpu_choices
        lines.append(
            f"| {f.name} | {f.avatars} | {f.choices / crowd.seconds:.1f} | "
            f"{np.percentile(lat, 50):.1f} ms | {np.percentile(lat, 99):.1f} ms | {f.stalls} | "
            f"{1000 * f.backend_cpu_s / cpu_choices if cpu_choices else float('nan'):.1f} | "
            f"{f.replay_cpu_s:.2f} |"
        )
    total = sum(f.choices for f in crowd.nodes.values())
    lines += [
        "",
        f"all: {total / crowd.seconds:.1f} choices/s; SELECT 1 round trip "
        f"{crowd.round_trip_ms:.3f} ms; failures: {len(crowd.failures)}"
        + (f" (first: {crowd.failures[0]})" if crowd.failures else ""),
    ]
    if crowd.standbys:
        lines += [
            "",
            "| standby machines | avatars served (model) | latency p50 (model) | primary's CPU "
            "sending WAL while loading | WAL out of the primary while loading |",
            "|---|---|---|---|---|",
        ]
        for k in (1, 2, 4, 8):
            m = model(crowd, k)
            lines.append(
                f"| {k} | {m['avatars']:.0f} | {m['latency_p50_ms']:.1f} ms | "
                f"{100 * m['primary_sending_share']:.1f}% of a core | "
                f"{m['primary_wal_out_mb_per_s']:.1f} MB/s |"
            )
        m = model(crowd, 1)
        lines.append(
            f"\nmodel inputs (measured): {m['cpu_ms_per_choice']:.1f} ms CPU per choice on a "
            f"standby, replay {100 * m['replay_cpu_share']:.1f}% of a core while the primary "
            f"loads, {m['choices_per_s_per_machine']:.0f} choices/s per {crowd.cores}-core machine"
            f"; the primary's walsender {100 * crowd.walsender_cpu_share:.1f}% of a core per "
            "standby while loading"
            f"; the avatar server's frames (this process) "
            f"{1000 * crowd.client_cpu_s_per_avatar_s:.1f} ms CPU per avatar-second: "
            f"about {crowd.cores / crowd.client_cpu_s_per_avatar_s:.0f} avatars per "
            f"{crowd.cores}-core avatar server"
        )
    return "\n".join(lines)
