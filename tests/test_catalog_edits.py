"""Editing the catalogue through the REST interface (issue 25), on real capture (CMU 131 and Bandai
walks): collections created, renamed, moved and deleted; a clip or one version deleted for real,
with its snippets, leaving a transition graph over them stale and never wrong (selections through
it are checked against the snippets that remain); an older version made current again; a
skeleton's joint map changed with its clips cut again (checked against the terminators' own
positions); `models` and `graphs` rows; clips cut at annotated segments (`modb split`); tokens on
every write, hostile names stored as text, an audit row per write; and the avatar WebSocket of a
server started with --require-token."""

from __future__ import annotations

import json
import os
from collections import Counter

import httpx
import numpy as np
import psycopg
import pytest
from support.browser import serving
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.database.cluster import ensure_writer_role

HOSTILE = "x'); DROP TABLE modb.clips; --"
GRAPH = "edits"


@pytest.fixture(scope="module")
def edits(cluster):
    """CMU 131 with a transition graph over it, two tokens, served; (dsn, tokens, client)."""
    with scratch_database(cluster, f"edits_{os.getpid()}") as dsn:
        with psycopg.connect(dsn, autocommit=True) as conn:
            ensure_writer_role(conn)
        trials = sorted(mocap("cmu", "131").glob("*.amc"))
        r = run_modb(dsn, "load", *trials, "--collection", "cmu/131", "--mirror", "-q")
        assert r.returncode == 0, r.stderr
        r = run_modb(
            dsn, "graph", "build", GRAPH, "--collection", "cmu/131", "--profile", "locomotion", "-q"
        )
        assert r.returncode == 0, r.stderr
        tokens = {}
        for name, role in (("editor", "loader"), ("viewer", "reader")):
            r = run_modb(dsn, "token", "create", name, "--role", role)
            assert r.returncode == 0, r.stderr
            tokens[name] = r.stdout.strip()
        with serving(dsn) as address:
            with httpx.Client(base_url=f"http://{address}", timeout=300) as client:
                yield dsn, tokens, client


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def query(dsn: str, sql: str, params=()):
    with psycopg.connect(dsn) as conn:
        return conn.execute(sql, params).fetchall()


def scalar(dsn: str, sql: str, params=()):
    return query(dsn, sql, params)[0][0]


def audited(dsn: str, action: str) -> list[tuple[str, str, str]]:
    return query(
        dsn,
        "SELECT token_name, db_role, object FROM modb.audit_log WHERE action = %s ORDER BY id",
        [action],
    )


WRITES = [
    ("POST", "/api/collections", {"path": "x"}),
    ("PATCH", "/api/collections/cmu", {"name": "y"}),
    ("DELETE", "/api/collections/cmu", None),
    ("DELETE", "/api/clips/1", None),
    ("DELETE", "/api/clips/1/versions/1", None),
    ("POST", "/api/clips/1/versions/1/current", None),
    ("PUT", "/api/skeletons/1/maps", {"joint_map": {}, "mirror_pairs": []}),
    ("POST", "/api/models", {"name": "m", "kind": "k", "data": {}}),
    ("PUT", "/api/models/1", {"data": {}}),
    ("DELETE", "/api/models/1", None),
    ("POST", "/api/graphs", {"name": "g", "kind": "k", "data": {}}),
    ("PUT", "/api/graphs/1", {"data": {}}),
    ("DELETE", "/api/graphs/1", None),
    ("POST", "/api/clips/1/retarget", {"skeleton": 1}),
    ("PUT", "/api/edit-scripts/x", {"commands": [{"op": "mirror"}]}),
    ("DELETE", "/api/edit-scripts/x", None),
    ("POST", "/api/edit-scripts/x/apply", {"clips": [1]}),
]


@pytest.mark.parametrize("method, path, body", WRITES, ids=[f"{m} {p}" for m, p, _ in WRITES])
def test_every_catalogue_write_needs_a_loader_token(edits, method, path, body):
    dsn, tokens, client = edits
    before = scalar(dsn, "SELECT count(*) FROM modb.audit_log")
    content = None if body is None else json.dumps(body)
    assert client.request(method, path, content=content).status_code == 401
    r = client.request(method, path, content=content, headers=bearer(tokens["viewer"]))
    assert r.status_code == 403, r.text
    r = client.request(method, path, content=content, headers=bearer("not-a-token"))
    assert r.status_code == 401
    assert scalar(dsn, "SELECT count(*) FROM modb.audit_log") == before


def test_collections_are_created_renamed_moved_and_deleted(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    r = client.post("/api/collections", json={"path": f"edits/{HOSTILE}/inner"}, headers=h)
    assert r.status_code == 201 and r.json()["path"] == f"edits/{HOSTILE}/inner"
    assert client.post("/api/collections", json={"path": "edits"}, headers=h).status_code == 409
    # the hostile name is a name, in the URL too
    hostile = httpx.URL(f"/api/collections/edits/{HOSTILE}")
    r = client.patch(hostile, json={"name": "renamed"}, headers=h)
    assert r.status_code == 200 and r.json()["path"] == "edits/renamed", r.text
    assert scalar(dsn, "SELECT count(*) FROM modb.clips") > 0  # the table is still there
    r = client.patch("/api/collections/edits/renamed/inner", json={"parent": ""}, headers=h)
    assert r.status_code == 200 and r.json()["path"] == "inner"
    # never into itself or below itself
    r = client.patch("/api/collections/edits", json={"parent": "edits/renamed"}, headers=h)
    assert r.status_code == 400 and "inside it" in r.json()["error"]
    # a name taken at the target
    client.post("/api/collections", json={"path": "edits/inner"}, headers=h)
    r = client.patch("/api/collections/inner", json={"parent": "edits"}, headers=h)
    assert r.status_code == 409
    assert (
        client.patch("/api/collections/nowhere", json={"name": "a"}, headers=h).status_code == 404
    )
    paths = {c["path"] for c in client.get("/api/collections").json()}
    assert {"edits", "edits/renamed", "edits/inner", "inner"} <= paths
    r = client.delete("/api/collections/edits", headers=h)
    assert r.status_code == 200 and r.json()["clips"] == 0
    paths = {c["path"] for c in client.get("/api/collections").json()}
    assert not any(p.startswith("edits") for p in paths) and "inner" in paths
    assert [a[2] for a in audited(dsn, "collection change")][:2] == [
        f"edits/{HOSTILE}",
        "edits/renamed/inner",
    ]
    assert all(a[:2] == ("editor", "modb_web") for a in audited(dsn, "collection delete"))


def _select_through(dsn: str, prev: list[int]) -> list[int | None]:
    with psycopg.connect(dsn) as conn:
        conn.execute("SELECT set_config('modb.graph', %s, false)", [GRAPH])
        return [
            conn.execute(
                "SELECT snippet_id FROM modb.select_next_snippet(%s, ARRAY[2.0, 0.0, 3.0], "
                "'locomotion')",
                [p],
            ).fetchone()[0]
            for p in prev
        ]


def test_deleting_a_clip_leaves_a_graph_stale_never_wrong(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    graph_id = scalar(dsn, "SELECT id FROM modb.graphs WHERE name = %s", [GRAPH])
    assert scalar(dsn, "SELECT modb.graph_is_current(%s)", [graph_id]) is True
    # the clip the selection through the graph leads to most often, from snippets of other clips
    starts = query(
        dsn,
        "SELECT gs.snippet_id, s.clip_id FROM modb.graph_snippets gs JOIN modb.snippets s "
        "ON s.id = gs.snippet_id WHERE gs.graph_id = %s AND s.id %% 25 = 0 ORDER BY 1",
        [graph_id],
    )
    chosen = _select_through(dsn, [p for p, _ in starts])
    clip_of = dict(query(dsn, "SELECT id, clip_id FROM modb.snippets"))
    led_to = Counter(
        clip_of[c] for c, (_, own) in zip(chosen, starts, strict=True) if clip_of[c] != own
    )
    victim = led_to.most_common(1)[0][0]
    doomed = {i for i, c in clip_of.items() if c == victim}
    prev = [p for c, (p, own) in zip(chosen, starts, strict=True) if c in doomed and own != victim]
    assert len(prev) >= 5 and len(doomed) > 50

    r = client.delete(f"/api/clips/{victim}", headers=h)
    assert r.status_code == 200 and r.json()["versions"] == 1, r.text
    for table in ("clips", "clip_versions", "snippet_sources", "snippets", "terminators"):
        column = "id" if table == "clips" else "clip_id"
        assert scalar(dsn, f"SELECT count(*) FROM modb.{table} WHERE {column} = %s", [victim]) == 0
    assert scalar(dsn, "SELECT modb.graph_is_current(%s)", [graph_id]) is False
    # its stored lists still name the gone snippets (an array has no foreign key): the selection
    # must never return one; every answer is a live snippet of the graph
    assert (
        scalar(
            dsn,
            "SELECT count(*) FROM modb.graph_transitions WHERE graph_id = %s "
            "AND to_snippets && %s::bigint[]",
            [graph_id, sorted(doomed)],
        )
        > 0
    )
    chosen = _select_through(dsn, prev)
    assert all(c is not None for c in chosen)
    assert not set(chosen) & doomed
    live = {
        r[0]
        for r in query(
            dsn,
            "SELECT gs.snippet_id FROM modb.graph_snippets gs JOIN modb.snippets s "
            "ON s.id = gs.snippet_id WHERE gs.graph_id = %s",
            [graph_id],
        )
    }
    assert set(chosen) <= live
    listing = run_modb(dsn, "graph", "list").stdout
    assert "STALE" in listing
    assert audited(dsn, "clip delete")[-1] == ("editor", "modb_web", f"clip {victim}")
    assert client.delete(f"/api/clips/{victim}", headers=h).status_code == 404


def _upload_as(client, token, path, name) -> dict:
    r = client.post(
        "/api/uploads",
        data={"collection": "versions"},
        files=[("file", (name, path.read_bytes(), "application/octet-stream"))],
        headers=bearer(token),
    )
    assert r.status_code == 200, r.text
    return r.json()["results"][0]


def _snippet_frames(dsn: str, clip: int) -> tuple[int, list[int]]:
    rows = query(
        dsn,
        "SELECT version, first_frame FROM modb.snippets WHERE clip_id = %s AND NOT mirrored "
        "ORDER BY first_frame",
        [clip],
    )
    assert len({v for v, _ in rows}) == 1
    return rows[0][0], [f for _, f in rows]


def test_an_older_version_is_made_current_again_and_a_version_deleted(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    # a Bandai walk, then another take's bytes under its name: versions 1 and 2 of one clip
    first, second = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[:2]
    clip = _upload_as(client, tokens["editor"], first, first.name)["clip_id"]
    _, cut_1 = _snippet_frames(dsn, clip)
    assert _upload_as(client, tokens["editor"], second, first.name)["version"] == 2
    _, cut_2 = _snippet_frames(dsn, clip)
    frames = dict(
        query(dsn, "SELECT version, n_frames FROM modb.clip_versions WHERE clip_id = %s", [clip])
    )
    assert frames[1] != frames[2]  # two different takes

    r = client.post(f"/api/clips/{clip}/versions/1/current", headers=h)
    assert r.status_code == 201 and r.json()["current_version"] == 3, r.text
    same = scalar(
        dsn,
        "SELECT a.rotations = b.rotations AND a.n_frames = b.n_frames AND a.meta = b.meta "
        "AND (b.load_params->>'restored_from')::int = 1 FROM modb.clip_versions a, "
        "modb.clip_versions b WHERE a.clip_id = %s AND b.clip_id = a.clip_id "
        "AND a.version = 1 AND b.version = 3",
        [clip],
    )
    assert same
    version, cut_3 = _snippet_frames(dsn, clip)
    assert version == 3 and r.json()["snippets"] == len(cut_3)
    assert cut_3 == cut_1 != cut_2  # cut as version 1 was
    assert client.get("/api/clips").json()  # the listing still answers
    current = [
        c
        for c in client.get(
            "/api/clips?collection="
            + str(scalar(dsn, "SELECT collection_id FROM modb.clips WHERE id = %s", [clip]))
        ).json()
        if c["id"] == clip
    ]
    assert current[0]["version"] == 3 and current[0]["n_frames"] == frames[1]

    # deleting the current version makes version 2 current, cut again as it was
    r = client.delete(f"/api/clips/{clip}/versions/3", headers=h)
    assert r.status_code == 200 and r.json()["current_version"] == 2, r.text
    assert _snippet_frames(dsn, clip) == (2, cut_2)
    # an older one goes without touching the current snippets
    ids = scalar(
        dsn, "SELECT array_agg(id ORDER BY id) FROM modb.snippets WHERE clip_id = %s", [clip]
    )
    assert client.delete(f"/api/clips/{clip}/versions/1", headers=h).status_code == 200
    assert (
        scalar(
            dsn, "SELECT array_agg(id ORDER BY id) FROM modb.snippets WHERE clip_id = %s", [clip]
        )
        == ids
    )
    r = client.delete(f"/api/clips/{clip}/versions/2", headers=h)
    assert r.status_code == 409 and "only version" in r.json()["error"]
    assert client.delete(f"/api/clips/{clip}/versions/7", headers=h).status_code == 404
    assert client.post(f"/api/clips/{clip}/versions/7/current", headers=h).status_code == 404
    # a collection holding clips goes only when asked to take them along
    r = client.delete("/api/collections/versions", headers=h)
    assert r.status_code == 409 and "holds 1 clips" in r.json()["error"]
    r = client.delete("/api/collections/versions?with_clips=true", headers=h)
    assert r.status_code == 200 and r.json()["clips"] == 1
    assert scalar(dsn, "SELECT count(*) FROM modb.snippets WHERE clip_id = %s", [clip]) == 0
    assert [a[2] for a in audited(dsn, "version restore")] == [f"clip {clip} version 1"]


def test_a_skeletons_joint_map_is_edited_with_its_etag_and_the_clips_cut_again(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    skeleton = scalar(
        dsn,
        "SELECT v.skeleton_id FROM modb.clip_versions v JOIN modb.clips c ON c.id = v.clip_id "
        "WHERE modb.collection_path(c.collection_id) = 'cmu/131' LIMIT 1",
    )
    r = client.get(f"/api/skeletons/{skeleton}/maps")
    assert r.status_code == 200
    etag, maps = r.headers["etag"], r.json()
    before = scalar(
        dsn,
        "SELECT count(*) FROM modb.snippets s JOIN modb.clip_versions v USING "
        "(clip_id, version) WHERE v.skeleton_id = %s",
        [skeleton],
    )
    old_ids = scalar(dsn, "SELECT max(id) FROM modb.snippets")
    joint_map = dict(maps["joint_map"], head=maps["joint_map"]["neck"])  # the head read at the neck
    body = {"joint_map": joint_map, "mirror_pairs": maps["mirror_pairs"]}
    url = f"/api/skeletons/{skeleton}/maps"
    assert client.put(url, json=body, headers=h).status_code == 428
    assert client.put(url, json=body, headers={**h, "If-Match": '"stale"'}).status_code == 409
    bad = dict(body, joint_map=dict(joint_map, head=HOSTILE))
    r = client.put(url, json=bad, headers={**h, "If-Match": etag})
    assert r.status_code == 400, r.text
    r = client.put(url, json=body, headers={**h, "If-Match": etag})
    assert r.status_code == 200 and r.json()["joint_map"]["head"] == joint_map["neck"], r.text
    assert r.headers["etag"] != etag and r.json()["clips_recut"] > 0
    after = scalar(
        dsn,
        "SELECT count(*) FROM modb.snippets s JOIN modb.clip_versions v USING "
        "(clip_id, version) WHERE v.skeleton_id = %s",
        [skeleton],
    )
    assert after == before == r.json()["snippets"]
    assert (
        scalar(
            dsn,
            "SELECT min(s.id) FROM modb.snippets s JOIN modb.clip_versions v USING "
            "(clip_id, version) WHERE v.skeleton_id = %s",
            [skeleton],
        )
        > old_ids
    )
    # the terminators now read the head where the neck is (positions: standard joints x xyz)
    names = scalar(dsn, "SELECT modb.standard_joints()")
    head, neck = names.index("head"), names.index("neck")
    positions = np.array(
        [
            r[0]
            for r in query(
                dsn,
                "SELECT positions FROM modb.terminators t JOIN modb.clip_versions v "
                "USING (clip_id, version) WHERE v.skeleton_id = %s LIMIT 500",
                [skeleton],
            )
        ]
    ).reshape(-1, len(names), 3)
    assert np.abs(positions[:, head] - positions[:, neck]).max() < 1e-6
    # put back, so the other tests see the skeleton as loaded
    r = client.put(url, json=maps | {}, headers={**h, "If-Match": r.headers["etag"]})
    assert r.status_code == 200
    assert audited(dsn, "skeleton maps")[-1][2] == f"skeleton {skeleton}"


def test_models_and_graphs_rows_are_created_replaced_and_deleted(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    data = {"means": [[0.1, 0.2]], "weights": [1.0]}
    r = client.post("/api/models", json={"name": HOSTILE, "kind": "gmm", "data": data}, headers=h)
    assert r.status_code == 201, r.text
    model = r.json()["id"]
    assert client.get(f"/api/models/{model}").json()["data"] == data
    again = client.post("/api/models", json={"name": HOSTILE, "kind": "gmm", "data": {}}, headers=h)
    assert again.status_code == 409
    # a replace of the data is the model's next version; the first is kept as it was
    r = client.put(f"/api/models/{model}", json={"data": [1, 2], "meta": {"note": "n"}}, headers=h)
    assert r.status_code == 201 and r.json()["replaced"] == ["data", "meta"], r.text
    second = r.json()["id"]
    assert r.json()["version"] == 2 and r.headers["location"] == f"/api/models/{second}"
    assert scalar(dsn, "SELECT data FROM modb.models WHERE id = %s", [second]) == [1, 2]
    assert scalar(dsn, "SELECT data FROM modb.models WHERE id = %s", [model]) == data
    # the meta alone is replaced in place
    r = client.put(f"/api/models/{second}", json={"meta": {"note": "m"}}, headers=h)
    assert r.status_code == 200 and r.json()["id"] == second
    assert scalar(dsn, "SELECT meta FROM modb.models WHERE id = %s", [second]) == {"note": "m"}
    assert client.put(f"/api/models/{model}", json={"meta": 3}, headers=h).status_code == 400
    assert (
        client.put(f"/api/models/{model}", json={"skeleton_id": 10**9}, headers=h).status_code
        == 404
    )
    for ident in (second, model):
        assert client.delete(f"/api/models/{ident}", headers=h).status_code == 200
        assert client.get(f"/api/models/{ident}").status_code == 404

    r = client.post(
        "/api/graphs", json={"name": "hand", "kind": "transitions", "data": {}}, headers=h
    )
    assert r.status_code == 400  # built, never written by hand
    r = client.post(
        "/api/graphs", json={"name": "walks", "kind": "motion", "data": {"nodes": []}}, headers=h
    )
    assert r.status_code == 201
    graph = r.json()["id"]
    assert (
        client.put(f"/api/graphs/{graph}", json={"data": {"nodes": [1]}}, headers=h).status_code
        == 200
    )
    assert client.put(f"/api/graphs/{graph}", json={"name": "x"}, headers=h).status_code == 400
    built = scalar(dsn, "SELECT id FROM modb.graphs WHERE name = %s", [GRAPH])
    assert client.put(f"/api/graphs/{built}", json={"data": {}}, headers=h).status_code == 400
    assert client.delete(f"/api/graphs/{graph}", headers=h).status_code == 200
    assert scalar(dsn, "SELECT count(*) FROM modb.graph_names WHERE name = 'walks'") == 0
    assert [a[2] for a in audited(dsn, "model create")] == [f"model {model}"]


def test_split_by_annotation_cuts_clips_on_the_source_frames(edits, tmp_path):
    dsn, tokens, client = edits
    clip, n_frames = query(
        dsn,
        "SELECT clip_id, n_frames FROM modb.current_clips WHERE collection = 'cmu/131' "
        "ORDER BY clip_id DESC LIMIT 1",
    )[0]
    segments = [("walk", 10, 250), ("turn", 200, 420), ("walk", 500, n_frames - 1)]
    spec = [f"{n}:{s}-{e}" for n, s, e in segments]
    r = run_modb(dsn, "annotate", f"id:{clip}", *[a for s in spec for a in ("--segment", s)])
    assert r.returncode == 0, r.stderr
    snippets = scalar(dsn, "SELECT count(*) FROM modb.snippets")
    r = run_modb(dsn, "split", f"id:{clip}", "--by-annotation", "--collection", "cmu/131 cuts")
    assert r.returncode == 0, r.stderr
    cut = query(
        dsn,
        "SELECT s.clip_id, s.annotation, s.first_frame, s.last_frame, c.name "
        "FROM modb.clip_segments s "
        "JOIN modb.clips c ON c.id = s.clip_id WHERE s.source_clip = %s ORDER BY 3",
        [clip],
    )
    assert [(a, f, la) for _, a, f, la, _ in cut] == sorted(segments, key=lambda s: s[1])
    assert scalar(dsn, "SELECT count(*) FROM modb.snippets") == snippets  # none of their own
    assert (
        "(kept)"
        in run_modb(
            dsn, "split", f"id:{clip}", "--by-annotation", "--collection", "cmu/131 cuts"
        ).stdout
    )
    # a cut's motion is the source's frames (read back through the client's model and in SQL)
    from modb.clips import read_motion
    from modb.database import pgarray

    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)  # as every modb connection reads real[] arrays
        for cut_id, _, first, last, _ in cut:
            motion = read_motion(conn, cut_id)
            rotations = conn.execute(
                "SELECT rotations[%s:%s] FROM modb.clip_versions WHERE clip_id = %s "
                "AND version = (SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s)",
                [first + 1, last + 1, clip, clip],
            ).fetchone()[0]
            assert motion.n_frames == last - first + 1
            stored = np.array(rotations, dtype=np.float32)  # real[], read as text: exact in float32
            assert np.array_equal(motion.rotations.astype(np.float32), stored)
    out = tmp_path / "cut.bvh"
    assert run_modb(dsn, "export", f"id:{cut[0][0]}", "--out", out).returncode == 0
    assert out.read_text().count("\n") > cut[0][3] - cut[0][2]
    # a cut never gets a version of its own, and goes with its source
    with (
        psycopg.connect(dsn) as conn,
        pytest.raises(psycopg.errors.CheckViolation, match="cut from"),
    ):
        conn.execute(
            "INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, "
            "translations) SELECT %s, skeleton_id, fps, n_frames, rotations, translations "
            "FROM modb.clip_versions WHERE clip_id = %s",
            [cut[0][0], clip],
        )
    h = bearer(tokens["editor"])
    assert client.delete(f"/api/clips/{clip}", headers=h).status_code == 200
    assert (
        scalar(dsn, "SELECT count(*) FROM modb.clips WHERE id = ANY(%s)", [[c[0] for c in cut]])
        == 0
    )


def test_the_avatar_socket_asks_a_token_when_reads_need_one(edits):
    from websockets.sync.client import connect

    dsn, tokens, _ = edits
    with serving(dsn, "--require-token") as address:
        assert httpx.get(f"http://{address}/api/collections").status_code == 401
        url = f"ws://{address}/ws/avatar"
        with connect(url, origin=f"http://{address}") as ws:
            ws.send(json.dumps({"type": "goal", "x": 1, "z": 1}))
            with pytest.raises(Exception):
                ws.recv(timeout=15)
            assert ws.close_code == 4401 and "token" in ws.close_reason
        with connect(url, origin=f"http://{address}") as ws:
            ws.send(json.dumps({"type": "auth", "token": "wrong"}))
            with pytest.raises(Exception):
                ws.recv(timeout=15)
            assert ws.close_code == 4401
        with connect(url, origin=f"http://{address}") as ws:
            ws.send(json.dumps({"type": "auth", "token": tokens["viewer"]}))
            assert json.loads(ws.recv(timeout=30))["type"] == "ready"


def test_edit_scripts_retargeting_and_joint_axes_through_rest(edits):
    dsn, tokens, client = edits
    h = bearer(tokens["editor"])
    walk = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[0]
    r = client.post(
        "/api/uploads",
        data={"collection": "rest edit"},
        files=[("file", (walk.name, walk.read_bytes(), "application/octet-stream"))],
        headers=h,
    )
    assert r.status_code == 200, r.text
    clip = r.json()["results"][0]["clip_id"]
    # an edit script named to inject SQL is only a name
    url = httpx.URL(f"/api/edit-scripts/{HOSTILE}")
    trim = [{"op": "trim", "start": 5, "end": 104}]
    assert (
        client.put(url, json={"commands": trim, "comment": "first 100"}, headers=h).status_code
        == 201
    )
    assert client.put(url, json={"commands": trim}, headers=h).status_code == 200
    assert client.put(url, json={"commands": []}, headers=h).status_code == 400
    listed = {s["name"]: s for s in client.get("/api/edit-scripts").json()}
    assert listed[HOSTILE]["commands"] == trim
    r = client.post(
        httpx.URL(f"/api/edit-scripts/{HOSTILE}/apply"), json={"collection": "rest edit"}, headers=h
    )
    assert r.status_code == 200, r.text
    assert r.json()["results"] == [
        {
            "clip_id": clip,
            "version": 2,
            "n_frames": 100,
            "snippets": r.json()["results"][0]["snippets"],
            "notes": [],  # a trim has none (an ik out of reach would: 0.30.0)
        }
    ]
    bad = client.post(
        httpx.URL(f"/api/edit-scripts/{HOSTILE}/apply"), json={"clips": "all"}, headers=h
    )
    assert bad.status_code == 400
    assert (  # no such script: the database says so with no_data_found (0.17.0)
        client.post("/api/edit-scripts/none/apply", json={"clips": [clip]}, headers=h).status_code
        == 404
    )
    assert client.delete(url, headers=h).status_code == 200
    assert client.delete(url, headers=h).status_code == 404
    # retargeting the walk onto the CMU skeleton: a new clip at the CMU clips' 120 fps
    cmu = scalar(
        dsn, "SELECT skeleton_id FROM modb.current_clips WHERE collection = 'cmu/131' LIMIT 1"
    )
    r = client.post(
        f"/api/clips/{clip}/retarget",
        json={"skeleton": cmu, "collection": "rest edit/cmu"},
        headers=h,
    )
    assert r.status_code == 201, r.text
    made = r.json()
    assert made["fps"] == 120 and made["collection"] == "rest edit/cmu" and made["clip_id"] != clip
    assert abs(made["n_frames"] - 1 - 99 * 4) <= 1  # 100 frames at 30 fps, now at 120
    assert (
        client.post(f"/api/clips/{clip}/retarget", json={"skeleton": 10**9}, headers=h).status_code
        == 404  # no such skeleton: no_data_found (0.17.0)
    )
    # the axes the retargeting derived are the skeleton's, and editable with its maps' ETag
    maps = client.get(f"/api/skeletons/{cmu}/maps")
    axes = maps.json()["joint_axes"]
    assert set(axes["joints"]) >= {"pelvis", "left_knee", "right_elbow"}
    changed = json.loads(json.dumps(axes))
    changed["joints"]["head"]["swing"] = [0.0, 0.0, 1.0]
    body = {k: maps.json()[k] for k in ("joint_map", "mirror_pairs")} | {"joint_axes": changed}
    r = client.put(
        f"/api/skeletons/{cmu}/maps", json=body, headers={**h, "If-Match": maps.headers["etag"]}
    )
    assert r.status_code == 200 and r.json()["clips_recut"] == 0, r.text
    assert scalar(
        dsn, "SELECT joint_axes->'joints'->'head'->'swing' FROM modb.skeletons WHERE id = %s", [cmu]
    ) == [0.0, 0.0, 1.0]
    changed["joints"]["head"]["joint"] = HOSTILE
    body["joint_axes"] = changed
    r = client.put(
        f"/api/skeletons/{cmu}/maps", json=body, headers={**h, "If-Match": r.headers["etag"]}
    )
    assert r.status_code == 400, r.text
    assert [a[2] for a in audited(dsn, "edit script apply")] == [HOSTILE]
