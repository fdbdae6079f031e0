"""The REST interface's writes (issue 25) on the real `modb serve`: tokens (401 without, 403 for a
reader's, a revoked one refused), uploads of real capture through the loader's path (one
transaction per file, idempotent, a new version for a changed file, file and line in errors,
nothing stored for a bad or oversized upload), a version's meta with ETag/If-Match (409 for a stale
write), the audit log (insert-only), the writer role (never a superuser), hostile names stored as
text, and the OpenAPI description naming every route."""

from __future__ import annotations

import builtins
import contextlib
import hashlib
import io
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from tempfile import SpooledTemporaryFile

import httpx
import psycopg
import pytest
import starlette.formparsers
import uvicorn
from support.browser import serving
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.database.cluster import WRITER_ROLE, ensure_writer_role
from modb.web.app import create_app

HOSTILE = "x'); DROP TABLE modb.clips; --"


@pytest.fixture(scope="module")
def rest(cluster):
    """A database with a loader and a reader token, served twice: with the default limits and with
    a 1 MB upload limit; (dsn, tokens, client, small-limit client)."""
    with scratch_database(cluster, f"rest_{os.getpid()}") as dsn:
        with psycopg.connect(dsn, autocommit=True) as conn:
            ensure_writer_role(conn)
        tokens = {}
        for name, role in (("editor", "loader"), ("viewer", "reader"), ("gone", "loader")):
            r = run_modb(dsn, "token", "create", name, "--role", role)
            assert r.returncode == 0, r.stderr
            tokens[name] = r.stdout.strip()
        assert run_modb(dsn, "token", "revoke", "gone").returncode == 0
        with serving(dsn) as address, serving(dsn, "--max-upload-mb", "1") as small:
            with httpx.Client(base_url=f"http://{address}", timeout=120) as client:
                with httpx.Client(base_url=f"http://{small}", timeout=120) as limited:
                    yield dsn, tokens, client, limited


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def scalar(dsn: str, query: str, params=()):
    with psycopg.connect(dsn) as conn:
        return conn.execute(query, params).fetchone()[0]


def walk_files(n: int = 2):
    files = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[:n]
    assert len(files) == n
    return files


def upload(client, token, paths, collection="rest/walks", names=None):
    files = [
        ("file", (name or p.name, p.read_bytes(), "application/octet-stream"))
        for p, name in zip(paths, names or [None] * len(paths))
    ]
    return client.post(
        "/api/uploads", data={"collection": collection}, files=files, headers=bearer(token)
    )


def test_tokens_are_stored_as_their_sha256_only(rest):
    dsn, tokens, _, _ = rest
    with psycopg.connect(dsn) as conn:
        rows = conn.execute("SELECT name, role, token_sha256 FROM modb.access_tokens").fetchall()
        text = conn.execute("SELECT string_agg(t::text, ' ') FROM modb.access_tokens t").fetchone()
    stored = {name: (role, bytes(h)) for name, role, h in rows}
    assert stored["editor"] == ("loader", hashlib.sha256(tokens["editor"].encode()).digest())
    assert stored["viewer"][0] == "reader"
    assert not any(token in text[0] for token in tokens.values())
    listing = run_modb(dsn, "token", "list").stdout
    assert "editor" in listing and "revoked" in listing and tokens["editor"] not in listing
    # a reader role may ask about one hash, not read the table
    with psycopg.connect(dsn) as conn:
        conn.execute("SET ROLE modb_reader")
        with pytest.raises(psycopg.errors.InsufficientPrivilege):
            conn.execute("SELECT * FROM modb.access_tokens")


def test_writes_need_a_live_loader_token(rest):
    dsn, tokens, client, _ = rest
    path = walk_files(1)
    before = scalar(dsn, "SELECT count(*) FROM modb.clip_versions")
    r = client.post("/api/uploads", files=[("file", (path[0].name, path[0].read_bytes()))])
    assert r.status_code == 401 and r.headers["www-authenticate"].startswith("Bearer")
    assert upload(client, tokens["viewer"], path).status_code == 403
    assert upload(client, tokens["gone"], path).status_code == 401
    assert upload(client, tokens["editor"] + "x", path).status_code == 401
    r = client.post(
        "/api/uploads", files=[("file", (path[0].name, b""))], headers={"Authorization": "Basic x"}
    )
    assert r.status_code == 401
    assert scalar(dsn, "SELECT count(*) FROM modb.clip_versions") == before
    # reads stay open on loopback
    assert client.get("/api/collections").status_code == 200


def test_an_upload_loads_through_the_loader_once_and_a_changed_file_is_a_new_version(rest):
    dsn, tokens, client, _ = rest
    first, second = walk_files(2)
    r = upload(client, tokens["editor"], [first, second])
    assert r.status_code == 200, r.text
    results = r.json()["results"]
    assert [x["status"] for x in results] == ["loaded", "loaded"]
    clip = results[0]["clip_id"]
    frames = scalar(dsn, "SELECT n_frames FROM modb.clip_versions WHERE clip_id = %s", [clip])
    assert results[0]["frames"] == frames > 0 and results[0]["snippets"] > 0
    assert (
        scalar(dsn, "SELECT count(*) FROM modb.snippets s WHERE s.clip_id = %s", [clip])
        == results[0]["snippets"]
    )
    source = scalar(dsn, "SELECT source_file FROM modb.clip_versions WHERE clip_id = %s", [clip])
    assert source == f"upload:{first.name}"
    # a collection named to inject SQL is only a name
    r = upload(client, tokens["editor"], [first], collection=HOSTILE)
    assert r.status_code == 200 and r.json()["results"][0]["status"] == "loaded"
    assert scalar(dsn, "SELECT count(*) FROM modb.collections WHERE name = %s", [HOSTILE]) == 1
    # the same bytes again: nothing stored
    again = upload(client, tokens["editor"], [first]).json()["results"][0]
    assert again["status"] == "unchanged" and again["clip_id"] == clip
    # other bytes under the same name: a new version of the same clip
    changed = upload(client, tokens["editor"], [second], names=[first.name]).json()["results"][0]
    assert changed["status"] == "loaded" and (changed["clip_id"], changed["version"]) == (clip, 2)
    with psycopg.connect(dsn) as conn:
        audit = conn.execute(
            "SELECT token_name, db_role, action, object FROM modb.audit_log "
            "WHERE action = 'upload' ORDER BY id"
        ).fetchall()
    assert audit[-1] == ("editor", "modb_web", "upload", f"clip {clip} version 2")
    assert len([a for a in audit if a[3].startswith(f"clip {clip} ")]) == 2


@contextlib.contextmanager
def _served_in_this_process(dsn: str):
    """`modb serve`'s app on a free port, in a thread of this process (so that a test sees every
    file it opens); yields an httpx client of it."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
        server = uvicorn.Server(uvicorn.Config(create_app(dsn, port=port), log_level="warning"))
        thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
        thread.start()
        deadline = time.monotonic() + 30
        while not server.started and thread.is_alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.started, "the app did not start"
        try:
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=120) as client:
                yield client
        finally:
            server.should_exit = True
            thread.join(30)


class _CountedSpool(SpooledTemporaryFile):
    """The form parser's spool of an uploaded file, adding up the bytes read back from it."""

    bytes_read = 0

    def read(self, *args):
        data = super().read(*args)
        _CountedSpool.bytes_read += len(data)
        return data


def test_an_upload_is_loaded_from_the_form_with_no_folder_written_or_walked(rest, monkeypatch):
    """The uploaded files reach the loader as the form spooled them: none is written under its
    name to a folder and read back from there, no folder is listed to pair an AMC with its ASF, and
    each upload's bytes are read from its spool once (the two AMC files share their ASF). In
    process, so that every open and every listing of a folder during the request is seen."""
    dsn, tokens, _, _ = rest
    trial = mocap("cmu", "131")
    names = ["131_01.amc", "131_02.amc", "131.asf"]
    opened, listed = [], []
    real_open, real_iterdir, real_scandir = io.open, Path.iterdir, os.scandir

    def spy_open(file, *args, **kwargs):
        if isinstance(file, (str, os.PathLike)):
            opened.append(str(file))
        return real_open(file, *args, **kwargs)

    def spy_iterdir(self):
        listed.append(str(self))
        return real_iterdir(self)

    def spy_scandir(path="."):
        listed.append(str(path))
        return real_scandir(path)

    files = [("file", (n, (trial / n).read_bytes())) for n in names]
    with _served_in_this_process(dsn) as client:
        monkeypatch.setattr(starlette.formparsers, "SpooledTemporaryFile", _CountedSpool)
        _CountedSpool.bytes_read = 0
        for module, name, spy in (
            (io, "open", spy_open),  # Path.open, read_bytes, write_bytes
            (builtins, "open", spy_open),
            (Path, "iterdir", spy_iterdir),
            (os, "scandir", spy_scandir),  # os.walk, os.listdir's kin
        ):
            monkeypatch.setattr(module, name, spy)
        r = client.post(
            "/api/uploads",
            data={"collection": "rest/from-the-form"},
            files=files,
            headers=bearer(tokens["editor"]),
        )
        monkeypatch.undo()
    assert r.status_code == 200, r.text
    assert [x["status"] for x in r.json()["results"]] == ["loaded", "loaded"]
    assert [f for f in opened if Path(f).name in names] == []
    assert listed == []
    assert _CountedSpool.bytes_read == sum(len(content) for _, (_, content) in files)
    # named as uploads are (the skeleton file too, not a temporary folder that is gone)
    with psycopg.connect(dsn) as conn:
        stored = conn.execute(
            "SELECT v.source_file, v.load_params->>'skeleton_file' FROM modb.clip_versions v "
            "JOIN modb.clips c ON c.id = v.clip_id "
            "WHERE c.collection_id = modb.find_collection('rest/from-the-form') ORDER BY 1"
        ).fetchall()
    assert stored == [
        ("upload:131_01.amc", "upload:131.asf"),
        ("upload:131_02.amc", "upload:131.asf"),
    ]


def test_a_bad_file_is_refused_with_its_line_and_stores_nothing(rest, tmp_path):
    dsn, tokens, client, _ = rest
    good = walk_files(1)[0]
    lines = good.read_text().splitlines()
    frame = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 5
    lines[frame] = lines[frame].replace(" ", " nan ", 1)
    bad = tmp_path / "broken_walk.bvh"
    bad.write_text("\n".join(lines) + "\n")
    before = scalar(dsn, "SELECT count(*) FROM modb.clip_versions")
    r = upload(client, tokens["editor"], [bad], collection="rest/bad")
    assert r.status_code == 400
    (result,) = r.json()["results"]
    assert result["status"] == "failed"
    assert result["message"].startswith(f"broken_walk.bvh:{frame + 1}:"), result["message"]
    assert str(tmp_path) not in result["message"] and "modb-upload-" not in result["message"]
    assert scalar(dsn, "SELECT count(*) FROM modb.clip_versions") == before
    # not a motion file at all, and a name with a path in it
    r = client.post(
        "/api/uploads", files=[("file", ("notes.txt", b"hello"))], headers=bearer(tokens["editor"])
    )
    assert r.status_code == 400 and "notes.txt" in r.json()["error"]
    r = client.post(
        "/api/uploads",
        files=[("file", ("../../etc/walk.bvh", good.read_bytes()))],
        headers=bearer(tokens["editor"]),
    )
    assert r.status_code in (200, 400)
    assert scalar(dsn, "SELECT count(*) FROM modb.clip_versions") <= before + 1
    assert (
        scalar(dsn, "SELECT count(*) FROM modb.clip_versions WHERE source_file LIKE '%%..%%'") == 0
    )


def test_an_oversized_upload_is_413_and_stores_nothing(rest):
    dsn, tokens, _, limited = rest
    big = sorted(mocap("bandai-2-dev", "data").glob("*.bvh"), key=lambda p: p.stat().st_size)[-2:]
    assert sum(p.stat().st_size for p in big) > 1 << 20  # one body larger than the limit
    before = scalar(dsn, "SELECT count(*) FROM modb.clip_versions")
    r = upload(limited, tokens["editor"], big)
    assert r.status_code == 413 and "1 MB" in r.json()["error"]
    assert scalar(dsn, "SELECT count(*) FROM modb.clip_versions") == before


def test_meta_writes_need_the_etag_and_a_stale_one_is_409(rest):
    dsn, tokens, client, _ = rest
    stored = upload(client, tokens["editor"], walk_files(1)).json()["results"][0]
    clip = stored["clip_id"]  # (an earlier test may have made this file a later version)
    url = f"/api/clips/{clip}/versions/{stored['version']}/meta"
    read = client.get(url)
    assert read.status_code == 200
    etag = read.headers["etag"]
    segments = [{"name": "walk", "start": 0, "end": 20}, {"name": HOSTILE, "start": 5, "end": 9}]
    meta = {"annotations": segments, "tags": ["walk", HOSTILE]}
    editor = bearer(tokens["editor"])
    assert client.put(url, json={"meta": meta}, headers=editor).status_code == 428
    viewer = {**bearer(tokens["viewer"]), "If-Match": etag}
    assert client.put(url, json={"meta": meta}, headers=viewer).status_code == 403
    first = client.put(url, json={"meta": meta}, headers={**editor, "If-Match": etag})
    assert first.status_code == 200, first.text
    assert first.headers["etag"] != etag
    # a second editor who read the old meta is refused, and shown the current one
    stale = client.put(url, json={"meta": {"tags": []}}, headers={**editor, "If-Match": etag})
    assert stale.status_code == 409 and stale.json()["meta"]["tags"] == ["walk", HOSTILE]
    assert stale.headers["etag"] == first.headers["etag"]
    with psycopg.connect(dsn) as conn:
        (meta,) = conn.execute(
            "SELECT meta FROM modb.clip_versions WHERE clip_id = %s AND version = %s",
            [clip, stored["version"]],
        ).fetchone()
        assert conn.execute("SELECT to_regclass('modb.clips')").fetchone()[0] is not None
    assert sorted(a["name"] for a in meta["annotations"]) == sorted(s["name"] for s in segments)
    # bad segments: 400, nothing changed
    n = client.get(url).json()["n_frames"]
    for bad in (
        [{"name": "late", "start": 0, "end": n}],
        [{"name": "back", "start": 9, "end": 3}],
        [{"name": "a:b", "start": 0, "end": 1}],
        [{"name": "x", "start": 0, "end": 1, "extra": 1}],
        "walk",
    ):
        now = client.get(url).headers["etag"]
        r = client.put(
            url, json={"meta": {"annotations": bad}}, headers={**editor, "If-Match": now}
        )
        assert r.status_code == 400, bad
    assert client.get(url).headers["etag"] == first.headers["etag"]
    assert client.get(f"/api/clips/{clip}/versions/99/meta").status_code == 404
    # listing by tag and by annotation name finds it, and only what matches (another clip stored)
    upload(client, tokens["editor"], walk_files(3)[2:])
    assert len(client.get("/api/clips").json()) > 1
    tagged = [c["id"] for c in client.get("/api/clips", params={"tag": HOSTILE}).json()]
    named = [c["id"] for c in client.get("/api/clips", params={"annotation": "walk"}).json()]
    assert tagged == [clip] and clip in named
    assert client.get("/api/clips", params={"annotation": "nothing so named"}).json() == []
    r = client.put(url, content=b"{", headers={**editor, "If-Match": etag})
    assert r.status_code == 400


def test_the_audit_log_is_insert_only_for_every_role(rest):
    dsn, tokens, client, _ = rest
    with psycopg.connect(dsn, autocommit=True) as conn:  # a row of its own: the writer may add one
        conn.execute("SET ROLE modb_web")
        conn.execute(
            "INSERT INTO modb.audit_log (token_name, action, object) VALUES ('t', 'test', 'x')"
        )
    assert scalar(dsn, "SELECT count(*) FROM modb.audit_log") > 0
    for role in ("modb_web", None):  # the writer, and the table's owner
        with psycopg.connect(dsn, autocommit=True) as conn:
            if role:
                conn.execute(f"SET ROLE {role}")
            for statement in (
                "UPDATE modb.audit_log SET token_name = 'someone'",
                "DELETE FROM modb.audit_log",
                "TRUNCATE modb.audit_log",
            ):
                with pytest.raises(psycopg.errors.InsufficientPrivilege):
                    conn.execute(statement)


def test_writes_never_run_as_a_superuser(rest, cluster):
    dsn, tokens, _, _ = rest
    with serving(dsn, "--write-user", cluster.os_user) as address:
        with httpx.Client(base_url=f"http://{address}", timeout=60) as client:
            r = upload(client, tokens["editor"], walk_files(1))
    assert r.status_code == 503 and "not a superuser" in r.json()["error"]


def test_writes_off_is_said_at_start_up(rest):
    """A writer role that cannot log in: `modb serve` warns as it starts, and a write is still a
    503 with the same reason."""
    dsn, tokens, _, _ = rest
    role = f"nobody_{os.getpid()}"
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    command = [sys.executable, "-m", "modb.cli", "--dsn", dsn, "serve", "--port", str(port)]
    proc = subprocess.Popen([*command, "--write-user", role], stderr=subprocess.PIPE, text=True)
    try:
        said = []
        for line in proc.stderr:  # up to the line that says where it listens
            said.append(line)
            if "http://" in line:
                break
        startup = "".join(said)
        assert "warning: writes are off" in startup and role in startup, startup
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=60) as client:
            for _ in range(100):
                with contextlib.suppress(httpx.TransportError):
                    if client.get("/api/collections").status_code == 200:
                        break
                time.sleep(0.1)
            r = upload(client, tokens["editor"], walk_files(1))
        assert r.status_code == 503 and role in r.json()["error"], r.text
    finally:
        proc.terminate()
        proc.wait(10)


def test_openapi_names_every_route(rest):
    _, _, client, _ = rest
    described = client.get("/api/openapi.json").json()
    assert described["openapi"].startswith("3.1")
    from modb.web.app import HEAVY_VIEWS, VIEWS

    from modb.web.catalog_writes import routes as write_routes

    described_ops = {
        (path.replace("{path}", "{path:path}"), method.upper())
        for path, ops in described["paths"].items()
        for method in ops
    }
    routes = {(p, "GET") for p in (*VIEWS, *HEAVY_VIEWS)} | {
        ("/api/uploads", "POST"),
        ("/api/clips/{clip_id}/versions/{version}/meta", "GET"),
        ("/api/clips/{clip_id}/versions/{version}/meta", "PUT"),
        ("/api/jobs", "POST"),
        ("/api/jobs/{ident}/cancel", "POST"),
    }
    routes |= {(r.path, m) for r in write_routes(None, None, None) for m in r.methods - {"HEAD"}}
    assert routes <= described_ops, routes - described_ops


def test_modb_annotate_adds_lists_and_removes_segments(rest):
    dsn, tokens, client, _ = rest
    third = walk_files(3)[2:]  # a clip no other test annotates
    clip = upload(client, tokens["editor"], third).json()["results"][0]["clip_id"]
    r = run_modb(dsn, "annotate", str(clip), "--segment", "step:2-10", "--segment", "turn:8-12")
    assert r.returncode == 0, r.stderr
    assert "step:2-10" in r.stdout and "turn:8-12" in r.stdout
    r = run_modb(dsn, "annotate", str(clip), "--segment", "late:0-999999")
    assert r.returncode == 2 and "late" in r.stderr
    assert run_modb(dsn, "annotate", str(clip), "--remove", "turn").returncode == 0
    with psycopg.connect(dsn) as conn:
        (meta,) = conn.execute(
            "SELECT meta FROM modb.clip_versions WHERE clip_id = %s ORDER BY version DESC LIMIT 1",
            [clip],
        ).fetchone()
    assert [a["name"] for a in meta["annotations"]] == ["step"]


def test_bodies_are_read_after_the_token_and_bad_ones_are_400(rest):
    """No token: 401 before any body is read (even a malformed one); then 411 without a length,
    400 for malformed multipart, NaN, JSON nested too deep and a string jsonb refuses; nothing
    stored."""
    dsn, tokens, client, _ = rest
    stored = upload(client, tokens["editor"], walk_files(1)).json()["results"][0]
    url = f"/api/clips/{stored['clip_id']}/versions/{stored['version']}/meta"
    etag = client.get(url).headers["etag"]
    h = {**bearer(tokens["editor"]), "If-Match": etag, "Content-Type": "application/json"}
    meta_before = scalar(
        dsn,
        "SELECT meta::text FROM modb.clip_versions WHERE clip_id = %s AND version = %s",
        [stored["clip_id"], stored["version"]],
    )
    assert client.put(url, content=b"{not json", headers={"If-Match": etag}).status_code == 401
    for body in (
        b'{"meta": {"tags": [NaN]}}',
        b'{"meta": {"x": ' + b"[" * 100_000 + b"]" * 100_000 + b"}}",
        b'{"meta": {"tags": ["a\\u0000b"]}}',
        b"\xff\xfe",
    ):
        r = client.put(url, content=body, headers=h)
        assert r.status_code == 400, (body[:30], r.status_code, r.text)

    def chunks():  # no Content-Length: sent chunked
        yield b'{"meta": {}}'

    assert client.put(url, content=chunks(), headers=h).status_code == 411
    r = client.post(
        "/api/uploads",
        content=b"--x\r\nbroken",
        headers={**bearer(tokens["editor"]), "Content-Type": "multipart/form-data; boundary=x"},
    )
    assert r.status_code == 400
    assert (
        scalar(
            dsn,
            "SELECT meta::text FROM modb.clip_versions WHERE clip_id = %s AND version = %s",
            [stored["clip_id"], stored["version"]],
        )
        == meta_before
    )


# --- issue 39: bodies checked before work, right statuses, messages without the driver's names ---


@pytest.fixture(scope="module")
def target(rest):
    """A walk of its own (clip id, skeleton id, maps ETag), loaded once for the tests below."""
    dsn, tokens, client, _ = rest
    walk = walk_files(4)[3]
    r = upload(client, tokens["editor"], [walk], collection="rest/targets")
    assert r.status_code == 200, r.text
    clip = r.json()["results"][0]["clip_id"]
    skeleton = client.get(f"/api/clips/{clip}").json()["skeleton_id"]
    return clip, skeleton


def counts(dsn: str) -> tuple[int, int, int]:
    return tuple(
        scalar(dsn, f"SELECT count(*) FROM modb.{table}")
        for table in ("audit_log", "clip_versions", "edit_scripts")
    )


# (method, path, body, what the 400's message must say); CLIP and SKELETON stand for the target's
BAD_BODIES = [
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "mirror": "no"}, "mirror: true"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "fps": 9999}, "fps: a number"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "fps": 0.01}, "1 to 1000 fps"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "fps": "30"}, "fps"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "fps": True}, "fps"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "1"}, "skeleton: a skeleton id"),
    ("POST", "/api/clips/CLIP/retarget", {"skeleton": "SKELETON", "mirorr": True}, "'mirorr'"),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [1.5]}, "clips[0]"),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [True]}, "clips[0]"),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": "all"}, "clips: a list"),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [[1]]}, "clips[0]"),
    ("PUT", "/api/edit-scripts/bad", {"commands": [1, "x", None]}, "command 1:"),
    ("PUT", "/api/edit-scripts/bad", {"commands": [{"op": "zap"}]}, 'unknown command "zap"'),
    ("PUT", "/api/edit-scripts/bad", {"commands": [{"op": "resample", "fps": 9999}]}, "fps"),
    (
        "PUT",
        "/api/edit-scripts/bad",
        {"commands": [{"op": "trim", "start": "1", "end": 2}]},
        "start",
    ),  # fmt: skip
    ("POST", "/api/collections", {"path": ["a"]}, "path: a collection path"),
    ("POST", "/api/models", {"name": 5, "kind": "k", "data": {}}, "name: a string"),
    (
        "POST",
        "/api/models",
        {"name": "m", "kind": "k", "data": {}, "skeleton_id": "x"},
        "skeleton_id",
    ),  # fmt: skip
    ("PUT", "/api/skeletons/SKELETON/maps", {"joint_map": {}, "mirror_pairs": []}, "joint_map"),
    (
        "PUT",
        "/api/skeletons/SKELETON/maps",
        {"joint_map": {"head": 1}, "mirror_pairs": []},
        "joint_map.head",
    ),  # fmt: skip
    ("PUT", "/api/skeletons/SKELETON/maps", "AXES", "joint_axes.joints.head.twist[0]"),
]


@pytest.mark.parametrize("method, path, body, says", BAD_BODIES, ids=[b[3] for b in BAD_BODIES])
def test_bodies_are_checked_by_type_and_range_before_any_work(rest, target, method, path, body,
                                                              says):  # fmt: skip
    """A field of the wrong type or out of range is a 400 naming it, with nothing stored or
    audited ("mirror": "no" is not true, joint axes of strings are not stored)."""
    dsn, tokens, client, _ = rest
    clip, skeleton = target
    url = path.replace("CLIP", str(clip)).replace("SKELETON", str(skeleton))
    headers = bearer(tokens["editor"])
    if "/maps" in url:
        maps = client.get(url)
        headers["If-Match"] = maps.headers["etag"]
        if body == "AXES":
            head = {"joint": "x", "twist": ["a", "b", "c"], "swing": [0, 0, 1]}
            axes = {"joints": {"head": head}}
            body = {k: maps.json()[k] for k in ("joint_map", "mirror_pairs")} | {"joint_axes": axes}
    if body.get("skeleton") == "SKELETON":
        body = {**body, "skeleton": skeleton}
    before = counts(dsn)
    r = client.request(method, url, json=body, headers=headers)
    assert r.status_code == 400, r.text
    assert says in r.json()["error"], r.json()["error"]
    assert counts(dsn) == before


def test_a_clip_named_twice_is_edited_once(rest, target):
    dsn, tokens, client, _ = rest
    clip, _ = target
    h = bearer(tokens["editor"])
    trim = {"commands": [{"op": "trim", "start": 0, "end": 9}]}
    assert client.put("/api/edit-scripts/trim10", json=trim, headers=h).status_code in (200, 201)
    before = scalar(dsn, "SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s", [clip])
    r = client.post("/api/edit-scripts/trim10/apply", json={"clips": [clip, clip]}, headers=h)
    assert r.status_code == 200, r.text
    assert [x["clip_id"] for x in r.json()["results"]] == [clip]
    assert (
        scalar(dsn, "SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s", [clip])
        == before + 1
    )
    detail = scalar(
        dsn, "SELECT detail FROM modb.audit_log WHERE action = 'edit script apply' ORDER BY id DESC"
    )
    assert detail == {"clips": [clip]}


def writer_processes(dsn: str) -> set[int]:
    return {
        pid
        for (pid,) in query_all(
            dsn,
            "SELECT pid FROM pg_stat_activity WHERE datname = current_database() AND usename = %s",
            [WRITER_ROLE],
        )
    }


def test_a_write_that_makes_frames_is_not_followed_by_its_server_process(rest, target):
    """A server process keeps part of the memory of the frames it computed: after an edit (or a
    retargeting, or an upload) its connection is closed, while other writes keep theirs pooled."""
    dsn, tokens, client, _ = rest
    clip, _ = target
    h = bearer(tokens["editor"])
    trim = {"commands": [{"op": "trim", "start": 0, "end": 9}]}
    assert client.put("/api/edit-scripts/trim10", json=trim, headers=h).status_code in (200, 201)
    pooled = writer_processes(dsn)
    assert pooled, "a plain write leaves its connection in the pool"
    r = client.post("/api/edit-scripts/trim10/apply", json={"clips": [clip]}, headers=h)
    assert r.status_code == 200, r.text
    after = writer_processes(dsn)
    # the pooled process that made the frames is gone (the pool may have opened another since)
    assert pooled - after, (pooled, after)


def test_creates_of_one_collection_at_once_give_one_201_and_one_audit_row(rest):
    dsn, tokens, client, _ = rest
    h = bearer(tokens["editor"])
    statuses: list[int] = []
    start = threading.Barrier(6)

    def create() -> None:
        start.wait()
        statuses.append(
            client.post("/api/collections", json={"path": "rest/raced"}, headers=h).status_code
        )

    threads = [threading.Thread(target=create) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(statuses) == [201] + [409] * 5, statuses
    audited = query_all(
        dsn,
        "SELECT 1 FROM modb.audit_log WHERE action = 'collection create' AND object = %s",
        ["rest/raced"],
    )
    assert len(audited) == 1, audited


def test_an_existing_collection_is_409_and_paths_are_names(rest):
    """POST of a collection that exists is 409 and not audited as a create; a path with an empty,
    '.' or '..' segment is refused naming the segment, and no collection so named is made."""
    dsn, tokens, client, _ = rest
    h = bearer(tokens["editor"])
    r = client.post("/api/collections", json={"path": "rest/made"}, headers=h)
    assert r.status_code == 201, r.text
    creates = len(query_all(dsn, "SELECT 1 FROM modb.audit_log WHERE action = 'collection create'"))
    again = client.post("/api/collections", json={"path": "rest/made"}, headers=h)
    assert again.status_code == 409 and "already exists" in again.json()["error"]
    assert (
        len(query_all(dsn, "SELECT 1 FROM modb.audit_log WHERE action = 'collection create'"))
        == creates
    )
    for path, segment in (("../..", "'..'"), ("a/./b", "'.'"), ("a//b", "''"), ("/a", "''")):
        r = client.post("/api/collections", json={"path": path}, headers=h)
        assert r.status_code == 400 and f"is {segment}" in r.json()["error"], (path, r.text)
    r = client.patch("/api/collections/rest%2Fmade", json={"name": ".."}, headers=h)
    assert r.status_code == 400 and "name" in r.json()["error"], r.text
    assert scalar(dsn, "SELECT count(*) FROM modb.collections WHERE name IN ('.', '..', '')") == 0


def query_all(dsn: str, sql: str, params=()):
    with psycopg.connect(dsn) as conn:
        return conn.execute(sql, params).fetchall()


def test_write_404s_name_what_is_missing(rest, target):
    """Like the reads: "no clip with id 99999", not "no such page"; an unknown clip, skeleton or
    script on retarget and apply is 404, not 400."""
    _, tokens, client, _ = rest
    clip, skeleton = target
    h = bearer(tokens["editor"])
    cases = [
        ("DELETE", "/api/models/99999", None, "no model with id 99999"),
        ("PUT", "/api/graphs/99999", {"data": {}}, "no graph with id 99999"),
        ("DELETE", "/api/clips/99999", None, "no clip with id 99999"),
        ("POST", "/api/clips/99999/versions/1/current", None, "no clip with id 99999"),
        ("POST", "/api/clips/99999/retarget", {"skeleton": skeleton}, "no clip with id 99999"),
        ("POST", f"/api/clips/{clip}/retarget", {"skeleton": 10**9}, "no skeleton with id"),
        ("POST", "/api/edit-scripts/nothing/apply", {"clips": [clip]}, "no edit script"),
        ("POST", "/api/edit-scripts/trim10/apply", {"clips": [99999]}, "no clip with id 99999"),
        ("DELETE", "/api/collections/no%2Fsuch", None, 'no collection "no/such"'),
    ]
    for method, path, body, says in cases:
        content = None if body is None else json.dumps(body)
        r = client.request(method, path, content=content, headers=h)
        assert r.status_code == 404, (path, r.text)
        assert says in r.json()["error"] and "no such page" not in r.json()["error"], r.text
    assert client.get("/api/nothing/here").json()["error"] == "no such page: /api/nothing/here"


def test_database_errors_are_said_without_the_drivers_names(rest, target):
    """Through REST: an edit the clip cannot take is a 400 without `plpy.Error:`. The central
    mapping, on errors the database really raises: no `plpy.Error:` or `spiexceptions.X:` prefix,
    a broken table rule in words, a result past a cap 413, a lock not granted a 503."""
    from modb.web.database_errors import answer

    dsn, tokens, client, _ = rest
    h = bearer(tokens["editor"])
    long = {"commands": [{"op": "trim", "start": 0, "end": 9_999_999}]}
    assert client.put("/api/edit-scripts/too-long", json=long, headers=h).status_code == 201
    r = client.post("/api/edit-scripts/too-long/apply", json={"clips": [target[0]]}, headers=h)
    assert r.status_code == 400 and '"end" must be a frame' in r.json()["error"], r.text
    assert not r.json()["error"].startswith(("plpy", "spiexceptions", "ERROR")), r.text
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(
            "CREATE FUNCTION pg_temp.refuse() RETURNS void LANGUAGE plpython3u AS "
            "$f$ plpy.error('no edit script \"nothing\"', hint='see modb.edit_scripts') $f$"
        )
        with pytest.raises(psycopg.Error) as raised:
            conn.execute("SELECT pg_temp.refuse()")
        assert "plpy.Error" in str(raised.value)  # what the driver says
        status, message = answer(raised.value)
        assert message == 'no edit script "nothing" (see modb.edit_scripts)'
        conn.execute(
            "CREATE FUNCTION pg_temp.bad() RETURNS void LANGUAGE plpython3u AS "
            "$f$ plpy.execute(\"INSERT INTO modb.collections (name) VALUES ('a/b')\") $f$"
        )
        with pytest.raises(psycopg.Error) as raised:  # a table rule broken inside PL/Python
            conn.execute("SELECT pg_temp.bad()")
        assert "spiexceptions.CheckViolation" in str(raised.value)
        status, message = answer(raised.value)
        assert status == 400 and "spiexceptions" not in message and "cannot hold '/'" in message
        conn.execute(
            "CREATE FUNCTION pg_temp.huge() RETURNS void LANGUAGE plpython3u AS "
            "$f$ plpy.error('the result would have 2,000,000 frames', sqlstate='54000') $f$"
        )
        with pytest.raises(psycopg.Error) as raised:  # past a cap: too large
            conn.execute("SELECT pg_temp.huge()")
        assert answer(raised.value) == (413, "the result would have 2,000,000 frames")
    with psycopg.connect(dsn) as holder, psycopg.connect(dsn) as other:
        holder.execute("SELECT 1 FROM modb.collections FOR UPDATE")
        with pytest.raises(psycopg.Error) as raised:
            other.execute("SELECT 1 FROM modb.collections FOR UPDATE NOWAIT")
        status, message = answer(raised.value)
        assert status == 503 and "try again" in message


JUNK = [None, "no", True, 1.5, -1, 0, 10**30, 1e308, [], [[1, "a"]], {}, {"a": {}}, "x" * 300,
        [None]]  # fmt: skip


def test_no_body_makes_a_write_answer_5xx(rest, target):
    """Every write endpoint that reads a body, each field of a good body replaced by each junk
    value, and junk as the whole body: never a 5xx."""
    dsn, tokens, client, _ = rest
    clip, skeleton = target
    h = bearer(tokens["editor"])
    maps = client.get(f"/api/skeletons/{skeleton}/maps")
    version = client.get(f"/api/clips/{clip}").json()["versions"][-1]["version"]
    meta_url = f"/api/clips/{clip}/versions/{version}/meta"
    model = client.post(
        "/api/models", json={"name": "fuzz", "kind": "k", "data": {}}, headers=h
    ).json()["id"]
    good = [
        ("POST", "/api/collections", {"path": "fuzz/a"}),
        ("PATCH", "/api/collections/fuzz%2Fnone", {"name": "b", "parent": ""}),
        ("POST", f"/api/clips/{clip}/retarget",
         {"skeleton": 10**9, "collection": "fuzz/r", "fps": 30, "mirror": False}),
        ("PUT", "/api/edit-scripts/fuzz",
         {"commands": [{"op": "trim", "start": 0, "end": 5}], "comment": "c"}),
        ("POST", "/api/edit-scripts/none/apply", {"clips": [clip]}),
        ("POST", "/api/edit-scripts/none/apply", {"collection": "fuzz/none"}),
        ("POST", "/api/models", {"name": "m", "kind": "k", "data": {}, "meta": {},
                                 "skeleton_id": skeleton}),
        ("PUT", f"/api/models/{model}", {"name": "fuzz", "data": {}, "meta": {},
                                         "skeleton_id": None}),
        ("POST", "/api/graphs", {"name": "g", "kind": "k", "data": {}}),
        ("PUT", f"/api/skeletons/{skeleton}/maps",
         {k: maps.json()[k] for k in ("joint_map", "mirror_pairs", "joint_axes")}),
        ("PUT", meta_url, {"meta": {"tags": ["x"]}}),
    ]  # fmt: skip
    answered = []
    for method, url, body in good:
        tries = [junk for junk in JUNK] + [
            {**body, key: junk} for key in body for junk in JUNK if junk != body[key]
        ]
        for attempt in tries:
            headers = dict(h)
            if url.endswith(("/maps", "/meta")):  # the current ETag: the junk reaches the write
                headers["If-Match"] = client.get(url).headers["etag"]
            r = client.request(method, url, json=attempt, headers=headers)
            answered.append(r.status_code)
            assert r.status_code < 500, (method, url, attempt, r.text)
            assert "plpy" not in r.text and "spiexceptions" not in r.text, r.text
    assert len(answered) > 400
    # nothing the junk left behind (joint axes of strings, say) breaks the next retargeting
    r = client.post(f"/api/clips/{clip}/retarget", json={"skeleton": skeleton}, headers=h)
    assert r.status_code < 500, r.text
