"""The request bodies the REST tests send that are malformed or refused (test_rest_writes,
test_catalog_edits, test_jobs, test_models, test_model_graphs_web, test_clip_jobs), frozen with the
status and the field named that the server answered them with before the bodies were declared as
pydantic models (tests/support/rest_refusals.json; test_rest_contract replays them).

A case is sent to one small site (site()): a fresh database holding one short walk, a loader token,
`modb serve` on it. Strings in a body or path stand for that site's objects: "$CLIP",
"$SKELETON", "$VERSION", "$N_FRAMES", "$MODEL" (the id a case before answered, `keep`), and
"$MAPS:joint_map" (the skeleton's maps as GET answers them). Cases run in order, as the tests run
them: some store what later ones meet (an edit script, a collection that is then 409)."""

from __future__ import annotations

import contextlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import psycopg
from support.browser import serving
from support.commands import run_modb
from support.data import mocap

from modb.access import tokens as access_tokens
from modb.database.cluster import ensure_writer_role

FIXTURE = Path(__file__).with_suffix(".json")  # the frozen cases
WALK = ("bandai-1", "data", "dataset-1_walk_active_001.bvh")  # 146 frames at 30 fps
HOSTILE = "x'); DROP TABLE modb.clips; --"


@dataclass
class Site:
    dsn: str
    client: httpx.Client
    token: str
    clip: int
    skeleton: int
    version: int
    n_frames: int
    kept: dict[str, Any]


@contextlib.contextmanager
def site(dsn: str):
    """One short walk in `dsn` (a fresh database), a loader token, `modb serve` on it."""
    with psycopg.connect(dsn, autocommit=True) as conn:
        ensure_writer_role(conn)
        token = access_tokens.create(conn, "contract", "loader")
    r = run_modb(dsn, "load", mocap(*WALK), "--collection", "walks", "-q")
    assert r.returncode == 0, r.stderr
    with psycopg.connect(dsn) as conn:
        clip, skeleton, version, n_frames = conn.execute(
            "SELECT c.clip_id, v.skeleton_id, c.version, c.n_frames FROM modb.current_clips c "
            "JOIN modb.clip_versions v USING (clip_id, version)"
        ).fetchone()
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as c:
        yield Site(dsn, c, token, clip, skeleton, version, n_frames, {})


def write_fixture(cases: list[dict[str, Any]]) -> None:
    """The frozen cases, one a line."""
    about = json.dumps(__doc__.split("\n\n")[0])
    lines = ",\n".join(json.dumps(c) for c in cases)
    FIXTURE.write_text(f'{{"about": {about},\n "cases": [\n{lines}\n]}}\n')


def named_field(message: str) -> str:
    """The field a 400's message names: 'fps' for "fps: a number from 1 to 1000 fps, got 9999",
    'mirorr' for "the body: unknown field 'mirorr'; ...", 'skeleton' for 'the body: "skeleton" is
    missing: ...', 'the body' for "the body: nothing to change: ..." and for a sentence on the
    body as a whole ("the body names the clips: ...")."""
    for pattern in (
        r"^(.*?): unknown field '([^']*)'",
        r"^(.*?): unknown field \"([^\"]*)\"",
        r'^(.*?): "([^"]+)" is missing',
    ):
        m = re.match(pattern, message)
        if m:
            parent, name = m.groups()
            return name if parent == "the body" else f"{parent}.{name}"
    head = message.split(": ", 1)[0]
    return "the body" if head.startswith("the body ") else head.strip('"')


def _fill(value: Any, s: Site) -> Any:
    if isinstance(value, str):
        if value.startswith("$MAPS:"):
            return s.client.get(f"/api/skeletons/{s.skeleton}/maps").json()[value[6:]]
        names = {"$CLIP": s.clip, "$SKELETON": s.skeleton, "$VERSION": s.version,
                 "$N_FRAMES": s.n_frames, **s.kept}  # fmt: skip
        if value in names:
            return names[value]
        for name, number in names.items():
            value = value.replace(name, str(number))
        return value
    if isinstance(value, list):
        return [_fill(v, s) for v in value]
    if isinstance(value, dict):
        return {k: _fill(v, s) for k, v in value.items()}
    return value


def send(s: Site, case: dict[str, Any]):
    """The case sent to the site (its If-Match the resource's current ETag where it asks one)."""
    url = _fill(case["path"], s)
    headers = {"Authorization": f"Bearer {s.token}"}
    if case.get("if_match"):
        headers["If-Match"] = s.client.get(url).headers["etag"]
    if "files" in case:
        files = [("file", (name, content.encode())) for name, content in case["files"]]
        r = s.client.request(case["method"], url, files=files, headers=headers)
    elif "raw" in case:
        raw = "".join(text * times for text, times in case["raw"]).encode("latin-1")
        headers["Content-Type"] = case.get("content_type", "application/json")
        r = s.client.request(case["method"], url, content=raw, headers=headers)
    elif "body" in case:
        content = json.dumps(_fill(case["body"], s)).encode()
        headers["Content-Type"] = "application/json"
        r = s.client.request(case["method"], url, content=content, headers=headers)
    else:
        r = s.client.request(case["method"], url, headers=headers)
    if case.get("keep") and r.is_success:
        s.kept[case["keep"]] = r.json()["id"]
    return r


def answer(r) -> dict[str, Any]:
    """What the freeze keeps of an answer: its status, and for a 400 its message and the field."""
    out: dict[str, Any] = {"status": r.status_code}
    if r.status_code == 400:
        body = r.json()
        error = body.get("error") or json.dumps(body)[:300]
        out |= {"error": error, "field": named_field(error)}
    return out


# --- the cases: (source, method, path, body) as the tests send them ------------------------------

# test_rest_writes.JUNK
JUNK = [None, "no", True, 1.5, -1, 0, 10**30, 1e308, [], [[1, "a"]], {}, {"a": {}}, "x" * 300,
        [None]]  # fmt: skip

BAD_BODIES = [  # test_rest_writes.BAD_BODIES
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "mirror": "no"}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "fps": 9999}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "fps": 0.01}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "fps": "30"}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "fps": True}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "1"}),
    ("POST", "/api/clips/$CLIP/retarget", {"skeleton": "$SKELETON", "mirorr": True}),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [1.5]}),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [True]}),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": "all"}),
    ("POST", "/api/edit-scripts/trim10/apply", {"clips": [[1]]}),
    ("PUT", "/api/edit-scripts/bad", {"commands": [1, "x", None]}),
    ("PUT", "/api/edit-scripts/bad", {"commands": [{"op": "zap"}]}),
    ("PUT", "/api/edit-scripts/bad", {"commands": [{"op": "resample", "fps": 9999}]}),
    ("PUT", "/api/edit-scripts/bad", {"commands": [{"op": "trim", "start": "1", "end": 2}]}),
    ("POST", "/api/collections", {"path": ["a"]}),
    ("POST", "/api/models", {"name": 5, "kind": "k", "data": {}}),
    ("POST", "/api/models", {"name": "m", "kind": "k", "data": {}, "skeleton_id": "x"}),
]
MAPS_URL = "/api/skeletons/$SKELETON/maps"
MAPS = {"joint_map": "$MAPS:joint_map", "mirror_pairs": "$MAPS:mirror_pairs"}
AXES = {"joints": {"head": {"joint": "x", "twist": ["a", "b", "c"], "swing": [0, 0, 1]}}}
META_URL = "/api/clips/$CLIP/versions/$VERSION/meta"


def _fuzz() -> list[tuple[str, str, Any]]:
    """test_rest_writes.test_no_body_makes_a_write_answer_5xx: each good body with each field
    replaced by each junk value, and junk as the whole body."""
    good = [
        ("POST", "/api/collections", {"path": "fuzz/a"}),
        ("PATCH", "/api/collections/fuzz%2Fnone", {"name": "b", "parent": ""}),
        ("POST", "/api/clips/$CLIP/retarget",
         {"skeleton": 10**9, "collection": "fuzz/r", "fps": 30, "mirror": False}),
        ("PUT", "/api/edit-scripts/fuzz",
         {"commands": [{"op": "trim", "start": 0, "end": 5}], "comment": "c"}),
        ("POST", "/api/edit-scripts/none/apply", {"clips": ["$CLIP"]}),
        ("POST", "/api/edit-scripts/none/apply", {"collection": "fuzz/none"}),
        ("POST", "/api/models", {"name": "m", "kind": "k", "data": {}, "meta": {},
                                 "skeleton_id": "$SKELETON"}),
        ("PUT", "/api/models/$MODEL", {"name": "fuzz", "data": {}, "meta": {},
                                       "skeleton_id": None}),
        ("POST", "/api/graphs", {"name": "g", "kind": "k", "data": {}}),
        ("PUT", MAPS_URL, {**MAPS, "joint_axes": "$MAPS:joint_axes"}),
        ("PUT", META_URL, {"meta": {"tags": ["x"]}}),
    ]  # fmt: skip
    out = []
    for method, url, body in good:
        tries = list(JUNK) + [
            {**body, key: junk} for key in body for junk in JUNK if junk != body[key]
        ]
        out += [(method, url, attempt) for attempt in tries]
    return out


def cases() -> list[dict[str, Any]]:
    """Every case, in the order to send them."""
    out: list[dict[str, Any]] = []

    def add(source: str, method: str, path: str, *body: Any, **extra: Any) -> None:
        case = {"source": source, "method": method, "path": path, **extra}
        if body:  # (a JSON null is a body too)
            (case["body"],) = body
        case["if_match"] = case.get("if_match") or path.endswith(("/maps", "/meta"))
        out.append(case)

    rest = "test_rest_writes.py"
    trim = {"commands": [{"op": "trim", "start": 0, "end": 9}]}
    add(rest, "PUT", "/api/edit-scripts/trim10", trim)  # what the cases below apply
    for method, path, body in BAD_BODIES:
        add(f"{rest}::BAD_BODIES", method, path, body)
    add(f"{rest}::BAD_BODIES", "PUT", MAPS_URL, {"joint_map": {}, "mirror_pairs": []})
    add(f"{rest}::BAD_BODIES", "PUT", MAPS_URL, {"joint_map": {"head": 1}, "mirror_pairs": []})
    add(f"{rest}::BAD_BODIES", "PUT", MAPS_URL, {**MAPS, "joint_axes": AXES})
    source = f"{rest}::test_meta_writes_need_the_etag_and_a_stale_one_is_409"
    for bad in (
        [{"name": "late", "start": 0, "end": "$N_FRAMES"}],
        [{"name": "back", "start": 9, "end": 3}],
        [{"name": "a:b", "start": 0, "end": 1}],
        [{"name": "x", "start": 0, "end": 1, "extra": 1}],
        "walk",
    ):
        add(source, "PUT", META_URL, {"meta": {"annotations": bad}})
    add(source, "PUT", META_URL, raw=[["{", 1]])
    source = f"{rest}::test_bodies_are_read_after_the_token_and_bad_ones_are_400"
    for raw in (
        [['{"meta": {"tags": [NaN]}}', 1]],
        [['{"meta": {"x": ', 1], ["[", 100_000], ["]", 100_000], ["}}", 1]],
        [['{"meta": {"tags": ["a\\u0000b"]}}', 1]],
        [["\xff\xfe", 1]],
    ):
        add(source, "PUT", META_URL, raw=raw)
    add(source, "POST", "/api/uploads", raw=[["--x\r\nbroken", 1]],
        content_type="multipart/form-data; boundary=x")  # fmt: skip
    source = f"{rest}::test_a_bad_file_is_refused_with_its_line_and_stores_nothing"
    add(source, "POST", "/api/uploads", files=[["notes.txt", "hello"]])
    source = f"{rest}::test_an_existing_collection_is_409_and_paths_are_names"
    add(source, "POST", "/api/collections", {"path": "rest/made"})
    add(source, "POST", "/api/collections", {"path": "rest/made"})
    for path in ("../..", "a/./b", "a//b", "/a"):
        add(source, "POST", "/api/collections", {"path": path})
    add(source, "PATCH", "/api/collections/rest%2Fmade", {"name": ".."})
    source = f"{rest}::test_write_404s_name_what_is_missing"
    add(source, "PUT", "/api/graphs/99999", {"data": {}})
    add(source, "POST", "/api/clips/99999/retarget", {"skeleton": "$SKELETON"})
    add(source, "POST", "/api/clips/$CLIP/retarget", {"skeleton": 10**9})
    add(source, "POST", "/api/edit-scripts/nothing/apply", {"clips": ["$CLIP"]})
    add(source, "POST", "/api/edit-scripts/trim10/apply", {"clips": [99999]})
    source = f"{rest}::test_database_errors_are_said_without_the_drivers_names"
    long = {"commands": [{"op": "trim", "start": 0, "end": 9_999_999}]}
    add(source, "PUT", "/api/edit-scripts/too-long", long)
    add(source, "POST", "/api/edit-scripts/too-long/apply", {"clips": ["$CLIP"]})
    source = f"{rest}::test_no_body_makes_a_write_answer_5xx"
    add(source, "POST", "/api/models", {"name": "fuzz", "kind": "k", "data": {}}, keep="$MODEL")
    for method, path, body in _fuzz():
        add(source, method, path, body)

    edits = "test_catalog_edits.py"
    source = f"{edits}::test_collections_are_created_renamed_moved_and_deleted"
    add(source, "POST", "/api/collections", {"path": "edits/renamed"})
    add(source, "PATCH", "/api/collections/edits", {"parent": "edits/renamed"})
    source = f"{edits}::test_models_and_graphs_rows_are_created_replaced_and_deleted"
    add(source, "POST", "/api/models", {"name": HOSTILE, "kind": "gmm", "data": {}}, keep="$GMM")
    add(source, "PUT", "/api/models/$GMM", {"meta": 3})
    add(source, "PUT", "/api/models/$GMM", {"skeleton_id": 10**9})
    add(source, "POST", "/api/graphs", {"name": "hand", "kind": "transitions", "data": {}})
    add(source, "POST", "/api/graphs", {"name": "walks", "kind": "motion", "data": {"nodes": []}},
        keep="$GRAPH")  # fmt: skip
    add(source, "PUT", "/api/graphs/$GRAPH", {"name": "x"})
    source = f"{edits}::test_edit_scripts_retargeting_and_joint_axes_through_rest"
    add(source, "PUT", "/api/edit-scripts/scripted", {"commands": []})
    add(source, "POST", "/api/edit-scripts/trim10/apply", {"clips": "all"})
    source = f"{edits}::test_a_skeletons_joint_map_is_edited_with_its_etag_and_the_clips_cut_again"
    add(source, "PUT", MAPS_URL, {"joint_map": {"head": HOSTILE}, "mirror_pairs": []})
    add(source, "PUT", MAPS_URL, {**MAPS, "joint_axes": {"joints": {"head": {
        "joint": HOSTILE, "twist": [1, 0, 0], "swing": [0, 1, 0]}}}})  # fmt: skip
    source = "test_jobs.py::test_rest_submits_with_a_loader_token_and_a_reader_token_only_reads"
    arguments = {"name": "rest", "collection": "cmu", "profile": "locomotion",
                 "min_turn_degrees": 0}  # fmt: skip
    add(source, "POST", "/api/jobs", {"kind": "nap", "arguments": arguments})
    source = "test_models.py::test_rest_lists_shows_samples_and_builds_with_a_loader_token"
    add(source, "POST", "/api/motion-models/walk_right/build",
        {"collection": "cmu16", "primitive": "right_step", "variance": 2})  # fmt: skip
    source = (
        "test_model_graphs_web.py::test_rest_graphs_of_models_need_the_etag_they_were_read_with"
    )
    broken = {"nodes": {"first": {"model_id": 999999, "type": "start"}}}
    add(source, "POST", "/api/graphs",
        {"name": "rest", "kind": "models", "skeleton_id": "$SKELETON", "data": broken})  # fmt: skip
    source = "test_clip_jobs.py::test_rest_retargets_a_whole_collection_as_a_job"
    add(source, "POST", "/api/collections/nowhere/retarget",
        {"skeleton": "$SKELETON", "collection": "over rest", "fps": 30})  # fmt: skip
    return out
