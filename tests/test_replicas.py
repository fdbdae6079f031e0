"""Hot standbys of the embedded database (issue 27): `modb db replica add|list|remove|promote` on a
cluster of this module's own, every read path run on a real standby, a load on the primary seen on
both standbys once replayed, and a standby promoted after the primary stops, the other following it.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import psycopg
import pytest
from support.browser import get, serving
from support.commands import run_modb
from support.data import mocap
from support.shared import NOT_DURABLE, throwaway_folder

from modb.database.cluster import Cluster
from modb.database import read_nodes
from modb.database.read_nodes import ReadNodes

COURSE = ("--to=4,4", "--to=-3,9", "--to=2,14", "--to=-6,4")
def db_cli(home: Path, *args: str, process: bool = False) -> subprocess.CompletedProcess:
    """`modb db ...` on the embedded database in `home` (MODB_HOME), in this process unless
    `process` (as a user runs it)."""
    if process:
        return subprocess.run(
            [sys.executable, "-m", "modb.cli", "db", *args],
            capture_output=True,
            text=True,
            env={**os.environ, "MODB_HOME": str(home)},
        )
    before = os.environ.get("MODB_HOME")
    os.environ["MODB_HOME"] = str(home)
    try:
        return run_modb("", "db", *args, process=False)  # `modb db` ignores --dsn
    finally:
        if before is None:
            del os.environ["MODB_HOME"]
        else:
            os.environ["MODB_HOME"] = before


def scalar(dsn: str, sql: str, params=()):
    with psycopg.connect(dsn, autocommit=True) as conn:
        return conn.execute(sql, params).fetchone()[0]


def wait_replayed(primary: str, standbys: list[str], timeout: float = 60) -> None:
    """Until every standby has replayed what the primary has written so far."""
    lsn = scalar(primary, "SELECT pg_current_wal_lsn()::text")
    deadline = time.monotonic() + timeout
    for s in standbys:
        while scalar(s, "SELECT pg_wal_lsn_diff(pg_last_wal_replay_lsn(), %s::pg_lsn)", [lsn]) < 0:
            assert time.monotonic() < deadline, f"{s} did not replay {lsn}"
            time.sleep(0.1)


def walks(folder: Path, pattern: str) -> Path:
    files = sorted(mocap("bandai-2-dev", "data").glob(pattern))
    folder.mkdir()
    for f in files:
        os.symlink(f, folder / f.name)
    return folder


@pytest.fixture(scope="module")
def nodes(tmp_path_factory):
    """A primary with a few Bandai walks and turns and a graph over them, and two standbys (the
    standbys' plumbing is the subject here, not the data: a dozen clips)."""
    data = walks(tmp_path_factory.mktemp("replicas") / "walks", "dataset-2_walk*_active_00[1-4]*")
    home = throwaway_folder("modb-replicas-")
    primary = Cluster(home)
    try:
        primary.init()
        with open(primary.datadir / "postgresql.auto.conf", "a") as conf:
            conf.write(NOT_DURABLE)  # a throwaway cluster (its standbys copy it)
        primary.start()
        dsn = primary.dsn()
        r = run_modb(dsn, "load", data, "--collection", "walks", "-q", process=False)
        assert r.returncode == 0, r.stderr
        r = run_modb(dsn, "graph", "build", "walks", "--collection", "walks", "-q", process=False)
        assert r.returncode == 0, r.stderr
        for name in ("r1", "r2"):
            r = db_cli(home, "replica", "add", name)
            assert r.returncode == 0, r.stderr
        listing = json.loads(db_cli(home, "replica", "list", "--json").stdout)
        yield home, dsn, {row["name"]: row["dsn"] for row in listing}
    finally:
        for d in [*sorted((home / "replicas").glob("*")), home]:
            if (d / "pgdata").exists():
                Cluster(home, node=d).stop()
        shutil.rmtree(home, ignore_errors=True)


def test_standbys_are_listed_streaming_read_only(nodes):
    home, primary, standbys = nodes
    assert sorted(standbys) == ["r1", "r2"]
    rows = json.loads(db_cli(home, "replica", "list", "--json").stdout)
    assert all(r["running"] and r["streaming"] for r in rows), rows
    with psycopg.connect(primary, autocommit=True) as conn:
        slots = dict(conn.execute("SELECT slot_name, active FROM pg_replication_slots").fetchall())
        assert slots == {"r1": True, "r2": True}
        assert conn.execute("SHOW max_slot_wal_keep_size").fetchone()[0] != "-1"
    for dsn in standbys.values():
        assert scalar(dsn, "SELECT pg_is_in_recovery()") is True
        assert scalar(dsn, "SHOW hot_standby_feedback") == "on"
        with pytest.raises(psycopg.errors.ReadOnlySqlTransaction):
            scalar(dsn, "INSERT INTO modb.collections (name) VALUES ('x') RETURNING id")
    text = db_cli(home, "replica", "list").stdout
    assert "r1" in text and "bytes behind" in text and standbys["r1"] in text
    assert db_cli(home, "replica", "url", "r2").stdout.strip() == standbys["r2"]
    # a slot of that name on the primary (another standby's?) is not taken over
    scalar(primary, "SELECT pg_create_physical_replication_slot('r9')")
    r = db_cli(home, "replica", "add", "r9", process=True)  # exit statuses: as a user's process
    assert r.returncode == 1 and "slot 'r9' already" in r.stderr, r.stderr
    assert not (home / "replicas" / "r9").exists()
    scalar(primary, "SELECT pg_drop_replication_slot('r9')")
    r = db_cli(home, "replica", "url", "nope", process=True)
    assert r.returncode == 1 and "no standby named 'nope'" in r.stderr
    # the avatar server's name for the primary is no standby's
    r = db_cli(home, "replica", "add", "primary", process=True)
    assert r.returncode == 1 and "other than 'primary'" in r.stderr, r.stderr


def synth_chain(dsn: str, out: Path, *args: str, seconds: float = 30) -> list[int]:
    """The snippets of a walk synthesized on `dsn` (two a second)."""
    r = run_modb(dsn, "synth", *COURSE, "--seconds", seconds, "--out", out, "--report-json",
                 out.with_suffix(".json"), "--lead-time", "0", "-q", *args,
                 process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    return [c["snippet_id"] for c in json.loads(out.with_suffix(".json").read_text())["chain"]]


def test_a_walk_on_a_standby_is_the_walk_on_the_primary(nodes, tmp_path):
    _, primary, standbys = nodes
    wait_replayed(primary, list(standbys.values()))
    on_primary = synth_chain(primary, tmp_path / "p.bvh")
    assert len(on_primary) == 60
    for name, dsn in standbys.items():
        assert synth_chain(dsn, tmp_path / f"{name}.bvh") == on_primary, name
        assert (tmp_path / f"{name}.bvh").read_bytes() == (tmp_path / "p.bvh").read_bytes()


def test_every_read_path_runs_on_a_standby(nodes):
    _, primary, standbys = nodes
    dsn = standbys["r1"]
    with psycopg.connect(dsn, autocommit=True) as conn:
        first = conn.execute("SELECT min(id) FROM modb.snippets").fetchone()[0]
        for sql in (
            "SELECT count(*) FROM modb.select_next_snippet(%(s)s, ARRAY[0, 2.0])",
            "SELECT count(*) FROM modb.select_next_snippets(%(s)s, ARRAY[1, 2.0], 5)",
            "SELECT count(*) FROM modb.select_next_snippets_reference(%(s)s, ARRAY[1, 2.0], 5)",
            "SELECT count(*) FROM modb.select_next_snippet_world(%(s)s, ARRAY[0, 0, 0], 0, "
            "ARRAY[3, 0, 3.0])",
            "SELECT count(*) FROM modb.synthesize(ARRAY[[3, 3], [-2, 6.0]], 20)",
            "SELECT count(*) FROM modb.snippet_pools()",
            "SELECT modb.default_graph('default', 'walks') IS NOT NULL",
        ):
            assert conn.execute(sql, {"s": first}).fetchone()[0], sql
        # under the named graph too (a session setting, no write)
        conn.execute("SET modb.graph = 'walks'")
        assert conn.execute(
            "SELECT count(*) FROM modb.select_next_snippet(%s, ARRAY[0, 2.0])", [first]
        ).fetchone()[0]
    with serving(dsn) as address:
        for path in ("/api/collections", "/api/clips", "/api/skeletons", "/api/graphs",
                     "/api/profiles", "/api/edit-scripts"):  # fmt: skip
            status, body = get(address, path)
            assert status == 200, (path, body)
        clip = get(address, "/api/clips")[1][0]["id"]
        for path in (f"/api/clips/{clip}", f"/api/clips/{clip}/frames?start=0&count=5"):
            assert get(address, path)[0] == 200, path
        assert walk_over_socket(address, seconds=30) > 0


def walk_over_socket(address: str, seconds: float) -> int:
    """Frames the avatar WebSocket streams after one click: 45 (1.5 s of walk, three choices),
    or fewer if `seconds` pass first."""
    from websockets.sync.client import connect

    frames = 0
    with connect(f"ws://{address}/ws/avatar", origin=f"http://{address}") as ws:
        assert json.loads(ws.recv(timeout=30))["type"] == "ready"
        ws.send(json.dumps({"type": "goal", "x": 3, "z": 3}))
        end = time.monotonic() + seconds
        while time.monotonic() < end and frames < 45:
            message = json.loads(ws.recv(timeout=30))
            assert message["type"] not in ("stopped", "refused"), message
            frames += message["type"] == "frame"
    return frames


def test_a_load_on_the_primary_reaches_both_standbys(nodes, tmp_path):
    _, primary, standbys = nodes
    more = walks(tmp_path / "more", "dataset-2_walk_active_03*")
    r = run_modb(primary, "load", more, "--collection", "more walks", "-q", process=False)
    assert r.returncode == 0, r.stderr
    wanted = scalar(
        primary,
        "SELECT count(*) FROM modb.snippets s JOIN modb.collections c ON c.id = s.collection_id "
        "WHERE c.name = 'more walks'",
    )
    assert wanted > 0
    wait_replayed(primary, list(standbys.values()))
    newest = scalar(primary, "SELECT max(id) FROM modb.snippets")
    for dsn in standbys.values():
        assert (
            scalar(
                dsn,
                "SELECT count(*) FROM modb.snippets s JOIN modb.collections c "
                "ON c.id = s.collection_id WHERE c.name = 'more walks'",
            )
            == wanted
        )
        # a walk that starts on the new data
        chain = synth_chain(
            dsn, tmp_path / "new.bvh", "--start", str(newest - 40), "--no-graph", seconds=5
        )
        assert chain[0] == newest - 40


def eventually(ready, what: str, seconds: float = 30, shown=lambda: None) -> None:
    """Polls ready() until it holds, failing after `seconds` (a generous bound, not a timing)."""
    deadline = time.monotonic() + seconds
    while not ready():
        assert time.monotonic() < deadline, f"not {what} within {seconds} s: {shown()}"
        time.sleep(0.05)


class Walker:
    """One avatar over the WebSocket: a click, then every message read as it arrives (a thread),
    with its arrival time."""

    def __init__(self, address: str, goal=(0.0, 60.0), settings: dict | None = None) -> None:
        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(
            connect(f"ws://{address}/ws/avatar", origin=f"http://{address}")
        )
        assert json.loads(self.ws.recv(timeout=30))["type"] == "ready"
        if settings:
            self.ws.send(json.dumps({"type": "settings", **settings}))
            assert json.loads(self.ws.recv(timeout=30))["type"] == "settings"
        self.ws.send(json.dumps({"type": "goal", "x": goal[0], "z": goal[1]}))
        self.notes: list[str] = []
        self.frames: list[float] = []  # arrival times
        self.nodes: list[str] = []  # the node of each choice
        self.trouble: list[dict] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                message = json.loads(text)
                if message["type"] == "frame":
                    self.frames.append(time.monotonic())
                elif message["type"] == "choice":
                    self.nodes.append(message["node"])
                elif message["type"] in ("stopped", "refused"):
                    self.trouble.append(message)
                elif message["type"] == "note":
                    self.notes.append(message["message"])
        except Exception as e:  # the socket closed under the test
            self.trouble.append({"type": "closed", "error": repr(e)})

    @staticmethod
    def read(seconds: float) -> None:
        time.sleep(seconds)

    def until(self, ready, what: str, seconds: float = 30) -> None:
        """Reads until ready() holds (polled), failing after `seconds`."""
        eventually(ready, what, seconds, lambda: (self.nodes[-5:], self.trouble, self.notes))

    def largest_gap(self) -> float:
        return float(np.diff(self.frames).max())

    def close(self) -> None:
        self._stack.close()
        self._reader.join(timeout=10)


def sessions_on(dsn: str) -> int:
    """Client sessions on the modb database of a node, by the server's own count."""
    return scalar(
        dsn,
        "SELECT count(*) FROM pg_stat_activity WHERE datname = 'modb' "
        "AND backend_type = 'client backend' AND pid <> pg_backend_pid()",
    )


def test_serve_spreads_avatar_sessions_over_the_standbys(nodes):
    _, primary, standbys = nodes
    # both caught up first: a standby behind the primary when a session opens is passed over
    wait_replayed(primary, list(standbys.values()))
    options = [a for dsn in standbys.values() for a in ("--standby", dsn)]
    with serving(primary, *options) as address:
        before = {name: sessions_on(dsn) for name, dsn in standbys.items()}
        walkers = [Walker(address, goal=(i - 3.0, 20.0)) for i in range(6)]
        try:  # each walking, its second snippet chosen
            eventually(lambda: all(len(w.nodes) >= 2 for w in walkers), "all walking",
                       shown=lambda: [(w.nodes, w.trouble) for w in walkers])  # fmt: skip
            served = [w.nodes[-1] for w in walkers]
            assert all(not w.trouble for w in walkers), [w.trouble for w in walkers]
            # all on standbys, three each
            assert sorted(served) == ["standby1"] * 3 + ["standby2"] * 3, served
            for i, (name, dsn) in enumerate(standbys.items()):
                assert sessions_on(dsn) - before[name] >= 3, name
        finally:
            for w in walkers:
                w.close()


def test_serve_caps_the_avatars_open_at_once(nodes):
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    _, primary, _ = nodes
    with serving(primary, "--max-avatars", "1") as address:
        first = Walker(address)
        try:
            with connect(f"ws://{address}/ws/avatar", origin=f"http://{address}") as ws:
                with pytest.raises(ConnectionClosed) as closed:
                    ws.recv(timeout=30)
            assert closed.value.rcvd.code == 1013, closed.value
            assert "--max-avatars" in closed.value.rcvd.reason
            first.until(lambda: len(first.frames) >= 30 or first.trouble, "walking")
            assert first.frames and not first.trouble, first.trouble
        finally:
            first.close()


def test_a_standby_stopped_mid_walk_moves_its_sessions(nodes):
    home, primary, standbys = nodes
    options = [a for dsn in standbys.values() for a in ("--standby", dsn)]
    with serving(primary, *options) as address:
        walker = Walker(address)
        try:
            walker.until(lambda: len(walker.nodes) >= 2 or walker.trouble, "walking")
            first = walker.nodes[-1]
            name = {"standby1": "r1", "standby2": "r2"}[first]
            stopped_at = len(walker.frames)
            Cluster(home, node=home / "replicas" / name).stop()
            # 100 frames (over 3 s at 30 fps) after the stop, and the moved walk's next choice
            walker.until(
                lambda: (
                    walker.trouble
                    or (len(walker.frames) - stopped_at > 100 and walker.nodes[-1] != first)
                ),
                "moved",
            )
            walker.read(0.5)
            assert not walker.trouble, walker.trouble
            assert walker.nodes[-1] != first  # moved to the other node
            assert len(walker.frames) - stopped_at > 100  # over 3 s at 30 fps, the move too
            gaps = np.diff(walker.frames[stopped_at - 1 :])
            assert gaps.max() < 0.5, gaps.max()
        finally:
            walker.close()
            Cluster(home, node=home / "replicas" / name).run_server()
    wait_replayed(primary, list(standbys.values()))


CONFLICTS = (
    "SELECT confl_tablespace + confl_lock + confl_snapshot + confl_bufferpin + confl_deadlock "
    "FROM pg_stat_database_conflicts WHERE datname = 'modb'"
)


def test_a_load_during_a_walk_on_a_standby_cancels_nothing(nodes, tmp_path):
    _, primary, standbys = nodes
    conflicts = scalar(standbys["r2"], CONFLICTS)
    with serving(primary, "--standby", standbys["r2"]) as address:
        walker = Walker(address)
        try:
            walker.until(lambda: len(walker.nodes) >= 2 or walker.trouble, "walking")
            more = walks(tmp_path / "during", "dataset-2_walk-turn-left_active_03[0-4]*")
            load = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "modb.cli",
                    "--dsn",
                    primary,
                    "load",
                    str(more),
                    "--collection",
                    "during a walk",
                    "-q",
                ],  # fmt: skip
                stderr=subprocess.PIPE,
                text=True,
            )
            while load.poll() is None:
                walker.read(0.1)
            assert load.returncode == 0, load.stderr.read()
            with psycopg.connect(primary, autocommit=True) as conn:
                conn.execute("VACUUM modb.snippets, modb.terminators")
            wait_replayed(primary, [standbys["r2"]])  # the vacuum too, and then 2 s more walk
            chosen = len(walker.nodes)
            walker.until(lambda: len(walker.nodes) >= chosen + 4 or walker.trouble, "walking on")
            assert not walker.trouble, walker.trouble
            assert set(walker.nodes) == {"standby1"}
            assert walker.largest_gap() < 0.5
            # no query was cancelled (the Avatar would ask again, hiding it from the walk)
            assert scalar(standbys["r2"], CONFLICTS) == conflicts
        finally:
            walker.close()


def test_a_moving_session_passes_over_a_standby_without_its_snippet(nodes, tmp_path):
    """r2 stops replaying; clips loaded on the primary reach r1 only; a walk on them moves, when
    r1 stops, to the primary, never to r2, which has not replayed the snippet it continues."""
    home, primary, standbys = nodes
    wait_replayed(primary, list(standbys.values()))
    r1 = Cluster(home, node=home / "replicas" / "r1")
    count = (
        "SELECT count(*) FROM modb.snippets s JOIN modb.collections c ON c.id = s.collection_id "
        "WHERE c.name = 'fresh'"
    )
    scalar(standbys["r2"], "SELECT pg_wal_replay_pause()")
    try:
        fresh = walks(tmp_path / "fresh", "dataset-2_walk-turn-right_active_00[1-4]*")
        r = run_modb(primary, "load", fresh, "--collection", "fresh", "-q", process=False)
        assert r.returncode == 0, r.stderr
        wait_replayed(primary, [standbys["r1"]])
        assert scalar(standbys["r2"], count) == 0 < scalar(standbys["r1"], count)
        # new sessions: never on r2, though it is tried first and serves none
        nodes_ = ReadNodes(primary, [("r2", standbys["r2"]), ("r1", standbys["r1"])])
        opened = [nodes_.open() for _ in range(3)]
        for _, conn in opened:
            assert conn.execute(count).fetchone()[0] > 0
            conn.close()
        assert [node.name for node, _ in opened] == ["r1"] * 3
        options = [a for dsn in standbys.values() for a in ("--standby", dsn)]
        with serving(primary, *options) as address:
            walker = Walker(address, settings={"collection": "fresh"})
            try:
                walker.until(lambda: len(walker.nodes) >= 3 or walker.trouble, "walking")
                assert walker.nodes and set(walker.nodes) == {"standby1"}, walker.nodes
                r1.stop()
                walker.until(
                    lambda: walker.trouble
                    or (walker.nodes[-1] == "primary" and any("on to primary" in n for n in
                                                              walker.notes)),
                    "moved on",
                )  # fmt: skip
                walker.read(1)  # and on, there
                assert not walker.trouble, walker.trouble
                assert walker.nodes[-1] == "primary", walker.nodes
                assert "standby2" not in walker.nodes
                assert any("on to primary" in n for n in walker.notes), walker.notes
            finally:
                walker.close()
                r1.run_server()
    finally:
        scalar(standbys["r2"], "SELECT pg_wal_replay_resume()")
    wait_replayed(primary, list(standbys.values()))


def test_promote_after_the_primary_stops(nodes, tmp_path, monkeypatch):
    home, primary, standbys = nodes
    wait_replayed(primary, list(standbys.values()))
    # what `modb serve` on the embedded database sees, looked up again as it changes
    monkeypatch.setenv("MODB_HOME", str(home))
    monkeypatch.setattr(read_nodes, "DISCOVER_SECONDS", 0.0)
    serving_nodes = ReadNodes.embedded(primary)
    assert [n.name for n in serving_nodes.standbys] == ["r1", "r2"]
    r = db_cli(home, "replica", "promote", "r1", process=True)
    assert r.returncode == 1 and "still running" in r.stderr  # two primaries would split the data
    assert db_cli(home, "stop").returncode == 0
    r = db_cli(home, "replica", "promote", "r1")
    assert r.returncode == 0, r.stderr
    assert f"old primary's data ({home / 'pgdata'})" in r.stdout, r.stdout
    url = db_cli(home, "url").stdout.strip()
    assert url == standbys["r1"]
    assert scalar(url, "SELECT pg_is_in_recovery()") is False
    # run again (as after a failure past the promotion), it finishes pointing the others
    r = db_cli(home, "replica", "promote", "r1")
    assert r.returncode == 0 and "old primary" not in r.stdout, (r.stdout, r.stderr)
    # loads go on there, and the other standby follows it
    more = walks(tmp_path / "after", "dataset-2_walk_active_02[0-2]*")
    r = run_modb(url, "load", more, "--collection", "after promotion", "-q", process=False)
    assert r.returncode == 0, r.stderr
    wait_replayed(url, [standbys["r2"]])
    count = (
        "SELECT count(*) FROM modb.clips c JOIN modb.collections k ON k.id = c.collection_id "
        "WHERE k.name = 'after promotion'"
    )
    assert scalar(standbys["r2"], count) == scalar(url, count) > 0
    rows = json.loads(db_cli(home, "replica", "list", "--json").stdout)
    assert [r["name"] for r in rows] == ["r2"] and rows[0]["streaming"]
    # and a standby is removed with its slot
    assert db_cli(home, "replica", "remove", "r2").returncode == 0
    assert not (home / "replicas" / "r2").exists()
    assert scalar(url, "SELECT count(*) FROM pg_replication_slots") == 0
    serving_nodes.refresh()
    assert serving_nodes.standbys == []  # r1 is the primary now, r2 is gone


def test_bench_crowd_runs_on_a_cluster_of_its_own(tmp_path):
    """`modb bench crowd` as BENCHMARKS.md runs it, short and on a few clips (its plumbing is the
    subject: a dozen walks and turns, two runs loaded halfway): every avatar on a standby, none
    failed, and the model's inputs reported (speed itself is the benchmark's, not a test's)."""
    data = tmp_path / "bandai-2"
    data.mkdir()
    for pattern in ("dataset-2_walk*_active_00[1-4]*", "dataset-2_run_active_00[1-2]*"):
        for f in sorted(mocap("bandai-2-dev", "data").glob(pattern)):
            os.symlink(f, data / f.name)
    # a temporary folder of its own (TMPDIR), to see it left empty
    temporary = throwaway_folder("modb-crowd-test-")
    try:
        r = subprocess.run(
            [
                sys.executable,
                "-m",
                "modb.cli",
                "bench",
                "crowd",
                "--avatars",
                "4",
                "--standbys",
                "2",
                "--seconds",
                "10",
                "--data",
                str(data),
                "--no-baseline",  # its own run, a minute more
            ],  # fmt: skip
            capture_output=True,
            text=True,
            env={**os.environ, "TMPDIR": str(temporary)},
        )
        assert r.returncode == 0, r.stderr
        cells = [[c.strip() for c in line.split("|")[1:-1]] for line in r.stdout.splitlines()]
        rows = {c[0]: c[1:] for c in cells if c and c[0] in ("s1", "s2", "primary")}
        assert sorted(rows) == ["s1", "s2"] and all(int(v[0]) == 2 for v in rows.values()), r.stdout
        assert "failures: 0" in r.stdout and "ms CPU per choice on a standby" in r.stdout
        assert "the primary's walsender" in r.stdout
        assert not list(temporary.glob("modb-crowd-*")), "its cluster is left"
    finally:
        shutil.rmtree(temporary, ignore_errors=True)
