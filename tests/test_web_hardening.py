"""`modb serve` under hostile or heavy use: deep and oversized WebSocket messages, duplicate Host
and Origin headers, and frame requests on a long clip (made at run time from a real Bandai BVH)
that must read only the frames asked for and may not crowd out the light requests."""

from __future__ import annotations

import asyncio
import base64
import concurrent.futures
import contextlib
import http.client
import itertools
import json
import os
import shutil
import socket
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np
import psycopg
import pytest
from support.browser import get, serving
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.database.cluster import Cluster
from modb.web import api
from modb.web.app import HEAVY_QUEUE, HEAVY_SLOTS, _configure, create_app
from modb.web.avatar_socket import MAX_MESSAGE_BYTES, MAX_MESSAGE_DEPTH
from modb.web.guard import HostOriginGuard, allowed_hosts

SOURCE = ("bandai-1", "data", "dataset-1_dance-short_normal_001.bvh")  # 1901 frames, the longest
LONG_FRAMES = 104_000
COLLECTION = "hardening/long"
# count=1 at these starts: the first frames, both sides of the first repeat's seam, the middle,
# the last frame.
STARTS = [0, 1, 1900, 1901, 1902, 51_234, LONG_FRAMES - 1]


# --- a long clip from real capture ----------------------------------------------------------------


def write_long_bvh(source: Path, target: Path, n_frames: int) -> int:
    """The source's hierarchy with its frames played over and over to n_frames frames, each repeat
    1 cm further along x (the first channel, joint_Root's Xposition), so that no two frames of the
    long clip are alike. Returns the source's frame count."""
    lines = source.read_text().splitlines()
    motion = lines.index("MOTION")
    frame_time = lines[motion + 2]
    assert lines[motion + 1].startswith("Frames:") and frame_time.startswith("Frame Time:")
    frames = [line.split() for line in lines[motion + 3 :] if line.strip()]
    with open(target, "w") as out:
        out.write("\n".join(lines[: motion + 1]) + f"\nFrames: {n_frames}\n{frame_time}\n")
        for i in range(n_frames):
            repeat, values = divmod(i, len(frames))
            first, *rest = frames[values]
            out.write(" ".join([repr(float(first) + repeat), *rest]) + "\n")
    return len(frames)


def frame_line(path: Path, frame: int) -> tuple[list[str], str]:
    """(the lines up to MOTION, the line of frame `frame`) read from the file as text: this test's
    own reading, not the loader's."""
    with open(path) as f:
        head = list(itertools.takewhile(lambda line: line.strip() != "MOTION", f))
        assert f.readline().startswith("Frames:") and f.readline().startswith("Frame Time:")
        line = next(itertools.islice(f, frame, None))
    return head, line


def expected_positions(path: Path, frame: int, unit_m: float, tmp: Path):
    """(joint names, (joints, 3) world positions in metres) of one frame of the long file, by
    bvhio (PyPI) reading a one-frame BVH of that frame's line."""
    head, line = frame_line(path, frame)
    single = tmp / f"frame_{frame}.bvh"
    single.write_text("".join(head) + "MOTION\nFrames: 1\nFrame Time: 0.0333333\n" + line)
    names, positions = bvhio_world_positions(str(single), unit_m)
    return names, positions[0]


@pytest.fixture(scope="module")
def long_clip(cluster, tmp_path_factory):
    """(dsn, the long BVH written, its clip id): the clip loaded without snippets."""
    folder = tmp_path_factory.mktemp("long")
    path = folder / "long_dance.bvh"
    assert write_long_bvh(mocap(*SOURCE), path, LONG_FRAMES) == 1901
    with scratch_database(cluster, f"hardening_{os.getpid()}") as dsn:
        r = run_modb(dsn, "load", path, "--collection", COLLECTION, "--no-snippets", "-q")
        assert r.returncode == 0, r.stderr
        with psycopg.connect(dsn) as conn:
            (clip_id,) = conn.execute("SELECT id FROM modb.clips").fetchone()
        yield dsn, path, clip_id


@pytest.fixture(scope="module")
def server(long_clip):
    """The real `modb serve` on the long clip's database; its host:port."""
    with serving(long_clip[0]) as address:
        yield address


def ok(address: str, path: str):
    status, body = get(address, path)
    assert status == 200, body
    return body


# --- frames: the right ones, and only those read --------------------------------------------------


def test_count_1_gives_the_frame_the_file_holds_at_every_start(server, long_clip, tmp_path):
    _, path, clip_id = long_clip
    info = ok(server, f"/api/clips/{clip_id}")
    assert info["n_frames"] == LONG_FRAMES
    unit_m = ok(server, f"/api/skeletons/{info['skeleton_id']}")["hierarchy"]["unit_m"]
    for start in STARTS:
        page = ok(server, f"/api/clips/{clip_id}/frames?start={start}&count=1")
        assert (page["start"], page["count"], page["n_frames"]) == (start, 1, LONG_FRAMES)
        assert len(page["positions"]) == len(page["rotations"]) == 1
        names, expected = expected_positions(path, start, unit_m, tmp_path)
        served = in_order(page["joints"], names, np.array(page["positions"]))[0]
        assert np.abs(served - expected).max() < 1e-4, start
    # A page that runs past the end stops at the last frame.
    page = ok(server, f"/api/clips/{clip_id}/frames?start={LONG_FRAMES - 2}&count=5")
    assert page["count"] == 2 and len(page["positions"]) == 2
    names, expected = expected_positions(path, LONG_FRAMES - 2, unit_m, tmp_path)
    assert (
        np.abs(in_order(page["joints"], names, np.array(page["positions"]))[0] - expected).max()
        < 1e-4
    )


class CountingCursor(psycopg.Cursor):
    """A cursor that adds up the bytes of every result value it receives from the server."""

    received = 0

    def execute(self, query, params=None, **kwargs):
        super().execute(query, params, **kwargs)
        result = self.pgresult
        if result is not None:
            CountingCursor.received += sum(
                len(result.get_value(row, col) or b"")
                for row in range(result.ntuples)
                for col in range(result.nfields)
            )
        return self


def test_a_frame_request_reads_only_its_frames_from_the_database(long_clip):
    """What the endpoint's view fetches from PostgreSQL, counted on its connection: a few KiB for
    one frame of a clip whose arrays hold tens of megabytes."""
    dsn, _, clip_id = long_clip
    with psycopg.connect(dsn) as conn:
        _configure(conn)  # as the server's pool does
        stored = conn.execute(
            "SELECT pg_column_size(rotations) + coalesce(pg_column_size(translations), 0) "
            "FROM modb.clip_versions WHERE clip_id = %s",
            [clip_id],
        ).fetchone()[0]
        conn.cursor_factory = CountingCursor
        CountingCursor.received = 0
        page = api.frames(conn, clip_id, None, 51_234, 1)
        one_frame = CountingCursor.received
        CountingCursor.received = 0
        api.frames(conn, clip_id, None, 51_234, 1000)
        thousand = CountingCursor.received
    assert page["count"] == 1 and stored > 10_000_000
    # The skeleton's hierarchy is most of it; one frame of 22 joints is 22 * (4 + 3) * 8 bytes.
    assert one_frame < 64 * 1024, (one_frame, stored)
    assert thousand - one_frame < 999 * 22 * 7 * 8 * 1.1, (thousand, one_frame)


@pytest.mark.parametrize(
    "query,message",
    [
        ("count=-1", "count must be 1-20000, got -1"),
        ("count=0", "count must be 1-20000, got 0"),
        ("count=20001", "count must be 1-20000, got 20001"),
        ("count=1.5", "count must be an integer, got '1.5'"),
        ("count=1e3", "count must be an integer, got '1e3'"),
        ("count=", "count must be an integer, got ''"),
        ("count=%2B1", "count must be an integer, got '+1'"),
        ("count=" + "9" * 30, "count must be an integer of at most 18 digits, got " + "9" * 30),
        ("start=-5", "start must be 0 or more, got -5"),
        ("start=0.5", "start must be an integer, got '0.5'"),
        ("start=" + "9" * 30, "start must be an integer of at most 18 digits, got " + "9" * 30),
        ("start=-" + "9" * 30, "start must be an integer of at most 18 digits, got -" + "9" * 30),
        (f"start={LONG_FRAMES}", f"start {LONG_FRAMES} is past the clip's last frame"),
        ("start=" + "9" * 18, "start " + "9" * 18 + " is past the clip's last frame"),
        ("version=" + "9" * 30, "version must be an integer of at most 18 digits"),
        ("start=1&start=2", "parameter 'start' is given more than once"),
    ],
)
def test_bad_start_and_count_get_400_with_a_message(server, long_clip, query, message):
    status, body = get(server, f"/api/clips/{long_clip[2]}/frames?{query}")
    assert status == 400 and body["error"].startswith(message), body


@pytest.mark.parametrize(
    "path,message",
    [
        ("/api/clips/" + "9" * 19, "clip id must be an integer of at most 18 digits"),
        ("/api/skeletons/" + "9" * 19, "skeleton id must be an integer of at most 18 digits"),
        ("/api/clips?collection=" + "9" * 19, "collection must be an integer of at most 18"),
    ],
)
def test_ids_too_long_for_the_database_get_400(server, path, message):
    status, body = get(server, path)
    assert status == 400 and body["error"].startswith(message), body


# --- many heavy requests at once ------------------------------------------------------------------


def test_heavy_requests_are_bounded_and_a_light_one_is_still_answered(server, long_clip):
    """The database is made to hold every frame request (a lock on the clip versions, which the
    collection listing does not read): HEAVY_SLOTS of them reach it, HEAVY_QUEUE wait their turn,
    the rest are answered 503 with Retry-After at once, and /api/collections is answered all the
    while. Once the lock goes, the waiting ones are answered with their frames."""
    dsn, _, clip_id = long_clip
    n = HEAVY_SLOTS + HEAVY_QUEUE + 12
    starts = [(k * 7919) % LONG_FRAMES for k in range(n)]

    def fetch(start: int):
        conn = http.client.HTTPConnection(server, timeout=120)
        try:
            conn.request("GET", f"/api/clips/{clip_id}/frames?start={start}&count=1")
            response = conn.getresponse()
            return start, response.status, response.getheader("Retry-After"), response.read()
        finally:
            conn.close()

    def waiting_on_the_lock(conn) -> int:
        return conn.execute(
            "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() "
            "AND wait_event_type = 'Lock' AND pid <> pg_backend_pid()"
        ).fetchone()[0]

    with (
        psycopg.connect(dsn) as locker,
        psycopg.connect(dsn, autocommit=True) as watcher,
        concurrent.futures.ThreadPoolExecutor(n) as pool,
    ):
        locker.execute("LOCK TABLE modb.clip_versions IN ACCESS EXCLUSIVE MODE")
        futures = [pool.submit(fetch, s) for s in starts]
        deadline = time.monotonic() + 90  # only for a server that never answers: not a measure
        while time.monotonic() < deadline:
            done = [f.result() for f in futures if f.done()]
            waiting = waiting_on_the_lock(watcher)
            if len(done) >= n - HEAVY_SLOTS - HEAVY_QUEUE and waiting >= HEAVY_SLOTS:
                break
            time.sleep(0.1)
        done = [f.result() for f in futures if f.done()]
        assert len(done) == n - HEAVY_SLOTS - HEAVY_QUEUE, (
            f"{len(done)} of {n} frame requests answered while the database held them all; "
            f"statuses {sorted(d[1] for d in done)}"
        )
        for start, status, retry_after, body in done:
            assert status == 503 and retry_after is not None and int(retry_after) > 0, body
            assert json.loads(body)["error"].startswith("busy:"), body
        assert waiting_on_the_lock(watcher) == HEAVY_SLOTS
        status, listing = get(server, "/api/collections")  # light: answered all the same
        assert status == 200 and COLLECTION in [c["path"] for c in listing], listing
        assert waiting_on_the_lock(watcher) == HEAVY_SLOTS  # still held: answered meanwhile
        assert sum(f.done() for f in futures) == len(done)
        locker.rollback()
        answers = [f.result() for f in futures]
    statuses = [a[1] for a in answers]
    assert set(statuses) <= {200, 503}, statuses
    assert statuses.count(200) == HEAVY_SLOTS + HEAVY_QUEUE, statuses
    reference = {}
    for start, status, _, body in answers:
        if status == 200:
            page = json.loads(body)
            reference[start] = ok(server, f"/api/clips/{clip_id}/frames?start={start}&count=1")
            assert page == reference[start]


# --- the WebSocket: what is refused, and the socket goes on ---------------------------------------


@contextlib.contextmanager
def avatar_socket(address: str):
    from websockets.sync.client import connect

    with connect(f"ws://{address}/ws/avatar", open_timeout=10, max_size=None) as ws:
        assert json.loads(ws.recv(10))["type"] == "ready"
        yield ws


def settings_answered(ws) -> None:
    """The socket still works: a good settings message is taken."""
    ws.send(json.dumps({"type": "settings", "lead_time": 0.5}))
    answer = json.loads(ws.recv(10))
    assert answer["type"] == "settings" and answer["settings"]["lead_time"] == 0.5, answer


DEEP = 100_000
UNDER_THE_LIMIT = (MAX_MESSAGE_BYTES - 16) // 2  # deep, and short enough to be parsed


@pytest.mark.parametrize(
    "message,reason",
    [
        ("[" * DEEP + "]" * DEEP, f"message too long: {2 * DEEP} bytes"),
        ("[" * UNDER_THE_LIMIT + "]" * UNDER_THE_LIMIT, "message nested too deep"),
        ('{"a":' * 5000 + "1" + "}" * 5000, "message nested too deep"),
        ("[" * (MAX_MESSAGE_DEPTH + 1) + "]" * (MAX_MESSAGE_DEPTH + 1), "message nested too deep"),
        # Brackets in a string are not nesting: this one is parsed, and is no goal.
        (json.dumps({"type": "goal", "x": "[" * 5000, "z": 0}), "a goal is"),
        (json.dumps({"type": "goal", "x": '\\"[' * 5000, "z": 0}), "a goal is"),
        ('{"type": "goal", "x": 1' + "0" * 400 + ', "z": 0}', "a goal is"),
        ('{"type": "settings", "lead_time": 1' + "0" * 400 + "}", "lead_time must be 0-2"),
        ('{"type": "goal", "x": 1' + "0" * 5000 + ', "z": 0}', "a number in the message has"),
        ('"' + '\\"' * 20000, "not JSON text"),
        (b"\x00\x01binary", "binary messages are not part of the protocol"),
        # JSON's types kept (issue 58): a text or a truth is not a number
        (json.dumps({"type": "goal", "x": "1", "z": 0}), "a goal is"),
        (json.dumps({"type": "goal", "x": True, "z": 0}), "a goal is"),
        (json.dumps({"type": "mode", "models": "walk", "goals": [["1", 2]]}),
         'no mode change: "goals"'),  # fmt: skip
    ],
    ids=[
        "100000-deep",
        "deep-under-the-size-limit",
        "deep-objects",
        "one-past-the-depth-limit",
        "brackets-in-a-string",
        "brackets-after-escapes-in-a-string",
        "huge-integer-goal",
        "huge-integer-lead-time",
        "integer-of-5000-digits",
        "unterminated-string-of-escapes",
        "binary",
        "goal-as-text",
        "goal-as-true",
        "mode-goal-as-text",
    ],
)
def test_a_bad_websocket_message_is_refused_and_the_socket_goes_on(server, message, reason):
    with avatar_socket(server) as ws:
        ws.send(message)
        answer = json.loads(ws.recv(10))
        assert answer["type"] == "refused" and answer["message"].startswith(reason), answer
        settings_answered(ws)


def test_messages_at_the_limits_are_taken(server):
    with avatar_socket(server) as ws:
        nested = {"knobs": {}}
        ws.send(json.dumps({"type": "settings", "lead_time": 0.25, **nested}))
        assert json.loads(ws.recv(10))["settings"]["lead_time"] == 0.25
        padded = json.dumps({"type": "settings", "lead_time": 0.3, "profile": "default"})
        padded = padded[:-1] + " " * (MAX_MESSAGE_BYTES - len(padded)) + "}"
        assert len(padded.encode()) == MAX_MESSAGE_BYTES
        ws.send(padded)
        assert json.loads(ws.recv(10))["settings"]["lead_time"] == 0.3
        deepest = "[" * MAX_MESSAGE_DEPTH + "]" * MAX_MESSAGE_DEPTH  # parsed: and is no message
        ws.send(deepest)
        answer = json.loads(ws.recv(10))
        assert answer["type"] == "refused" and "unknown message type" in answer["message"], answer
        settings_answered(ws)


# --- duplicate Host and Origin --------------------------------------------------------------------


def raw_get(address: str, path: str, headers: list[tuple[str, str]]) -> tuple[int, bytes]:
    """GET with exactly these headers, repeated ones included (http.client sends them as given)."""
    conn = http.client.HTTPConnection(address, timeout=30)
    try:
        conn.putrequest("GET", path, skip_host=True, skip_accept_encoding=True)
        for name, value in headers:
            conn.putheader(name, value)
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


def raw_handshake(address: str, headers: list[tuple[str, str]]) -> int:
    """The HTTP status a WebSocket opening handshake to /ws/avatar with these headers gets."""
    host, port = address.rsplit(":", 1)
    key = base64.b64encode(os.urandom(16)).decode()
    request = [
        "GET /ws/avatar HTTP/1.1",
        *(f"{name}: {value}" for name, value in headers),
        "Upgrade: websocket",
        "Connection: Upgrade",
        f"Sec-WebSocket-Key: {key}",
        "Sec-WebSocket-Version: 13",
    ]
    with socket.create_connection((host, int(port)), timeout=30) as s:
        s.sendall(("\r\n".join(request) + "\r\n\r\n").encode())
        reply = b""
        while b"\r\n" not in reply:
            chunk = s.recv(4096)
            if not chunk:
                break
            reply += chunk
    return int(reply.split(b" ", 2)[1])


def duplicates(address: str) -> list[list[tuple[str, str]]]:
    own = f"http://{address}"
    return [
        [("Host", address), ("Origin", "http://evil.example"), ("Origin", own)],
        [("Host", address), ("Origin", own), ("Origin", "http://evil.example")],
        [("Host", address), ("Origin", own), ("Origin", own)],
        [("Host", "evil.example"), ("Host", address)],
        [("Host", address), ("Host", address)],
    ]


def test_duplicate_host_or_origin_is_refused_over_http(server):
    assert raw_get(server, "/api/collections", [("Host", server)])[0] == 200
    for headers in duplicates(server):
        for path in ("/api/collections", "/", "/static/viewer.js"):
            status, body = raw_get(server, path, headers)
            # uvicorn's HTTP parser refuses a second Host itself (400); the guard refuses the rest.
            assert status in (400, 403), (headers, path, status, body)
            if any(name == "Origin" for name, _ in headers):
                assert status == 403 and b"2 Origin headers are refused" in body, (headers, body)


@contextlib.contextmanager
def in_process_server(dsn: str, ws: str):
    """create_app under uvicorn in this process, with the given WebSocket implementation (`modb
    serve` takes uvicorn's default; wsproto passes repeated headers on to the app)."""
    import uvicorn

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    app = create_app(dsn, "127.0.0.1", port)
    config = uvicorn.Config(app, host="127.0.0.1", port=port, ws=ws, log_level="error")
    uv = uvicorn.Server(config)
    thread = threading.Thread(target=uv.run, daemon=True)
    thread.start()
    try:
        for _ in range(200):
            if uv.started:
                break
            time.sleep(0.05)
        assert uv.started, "uvicorn did not start"
        yield f"127.0.0.1:{port}"
    finally:
        uv.should_exit = True
        thread.join(30)


@pytest.mark.parametrize("ws", ["auto", "wsproto"])
def test_duplicate_host_or_origin_is_refused_on_the_websocket(long_clip, ws):
    with in_process_server(long_clip[0], ws) as address:
        assert raw_handshake(address, [("Host", address), ("Origin", f"http://{address}")]) == 101
        for headers in duplicates(address):
            # 403: the guard; 400: the WebSocket library refused it before the app saw it.
            assert raw_handshake(address, headers) in (400, 403), (ws, headers)
        if ws == "wsproto":  # it hands every header to the app: the guard's own refusal
            for headers in duplicates(address)[:3]:
                assert raw_handshake(address, headers) == 403, headers


def guard_answer(scope_type: str, headers: list[tuple[str, str]]) -> tuple[str, object]:
    """What HostOriginGuard does with one request: ("passed", None), or its refusal (the HTTP
    status, or the WebSocket close code and reason)."""
    hosts = allowed_hosts("127.0.0.1", 8765)
    passed = []

    async def app(scope, receive, send):
        passed.append(scope)

    sent = []

    async def send(message):
        sent.append(message)

    async def receive():
        return {"type": "http.request", "body": b""}

    scope = {
        "type": scope_type,
        "path": "/ws/avatar" if scope_type == "websocket" else "/api/collections",
        "headers": [(k.lower().encode("latin-1"), v.encode("latin-1")) for k, v in headers],
    }
    asyncio.run(HostOriginGuard(app, hosts)(scope, receive, send))
    if passed:
        return "passed", None
    if scope_type == "websocket":
        return "closed", (sent[0]["code"], sent[0]["reason"])
    body = json.loads(next(m["body"] for m in sent if m["type"] == "http.response.body"))
    return "refused", (sent[0]["status"], body["error"])


@pytest.mark.parametrize("scope_type", ["http", "websocket"])
def test_the_guard_refuses_repeated_host_and_origin_whatever_their_order(scope_type):
    """The guard itself, for every server in front of it (uvicorn's HTTP parser refuses a second
    Host before the guard sees it; another server need not)."""
    own, evil = "127.0.0.1:8765", "evil.example"
    assert guard_answer(scope_type, [("Host", own), ("Origin", f"http://{own}")])[0] == "passed"
    for name, values in [
        ("Host", [evil, own]),
        ("Host", [own, evil]),
        ("Host", [own, own]),
        ("Origin", [f"http://{evil}", f"http://{own}"]),
        ("Origin", [f"http://{own}", f"http://{evil}"]),
        ("Origin", [f"http://{own}", f"http://{own}"]),
    ]:
        headers = [("Host", own)] if name == "Origin" else []
        headers += [(name, v) for v in values]
        outcome, detail = guard_answer(scope_type, headers)
        code = 1008 if scope_type == "websocket" else 403
        assert outcome != "passed" and detail[0] == code, (name, values, outcome, detail)
        assert f"2 {name} headers are refused" in detail[1], detail


# --- the database goes away and comes back (issue 39) ---------------------------------------------


@pytest.fixture
def own_cluster():
    """A private cluster of this test's own (it is stopped under a running `modb serve`)."""
    home = Path(tempfile.mkdtemp(prefix="modb-gone-"))
    home.chmod(0o711)  # the cluster's OS user (postgres, when run as root) passes through it
    cluster = Cluster(home / "cluster")
    cluster.start()  # with database modb and the extension
    try:
        yield cluster
    finally:
        cluster.stop()
        shutil.rmtree(home, ignore_errors=True)


def test_a_database_that_went_away_is_said_at_once_and_the_server_comes_back(own_cluster):
    """After the database stops, a request is answered 503 saying the database is unreachable and
    where (not "busy" after the pool's 30 s wait: the client gives up at 20 s), with Retry-After;
    once it runs again the same server answers by itself."""
    with serving(own_cluster.dsn()) as address:
        with httpx.Client(base_url=f"http://{address}", timeout=20) as client:
            assert client.get("/api/collections").status_code == 200
            own_cluster.stop()
            for path in ("/api/collections", "/api/clips/1"):
                r = client.get(path)
                assert r.status_code == 503, r.text
                error = r.json()["error"]
                assert "database is unreachable" in error and str(own_cluster.socket_dir) in error
                assert r.headers["retry-after"].isdigit()
            own_cluster.run_server()
            for _ in range(60):
                r = client.get("/api/collections")
                if r.status_code == 200:
                    break
                assert r.status_code == 503, r.text
                time.sleep(1)
            assert r.status_code == 200, r.text
