"""Graphs of motion models (modb.graphs kind 'models') edited through the REST interface and the
web view's editor, in headless Chromium (issue 45, item 1): on CMU 16's walks with a model of the
left steps and one of the right steps, a graph of them made in SQL is opened in the page, a node
and a transition added, a node's type set, saved and read back in SQL; a broken graph (a node no
transition reaches) is refused with the database's reason shown on the page and nothing stored; a
node removed; a new graph made from the page. The REST rules: a graph of models is read with an
ETag and replaced only with If-Match naming it (428 without, 409 when stale, the new ETag after),
by a loader's token only; the database's refusal comes back with its reason."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import httpx
import psycopg
import pytest
from psycopg.types.json import Jsonb
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select
from support.browser import module_page, serving, severe_console_entries
from support.commands import run_modb

from modb.database.cluster import ensure_writer_role

GRAPH = "walk"
LEFT, RIGHT = "cmu16_left_step", "cmu16_right_step"


@dataclass
class Site:
    address: str
    dsn: str
    tokens: dict[str, str]
    models: dict[str, int]  # name: id
    skeleton: int
    graph: int  # the graph of models made in SQL


def query(dsn: str, sql: str, params=()):
    with psycopg.connect(dsn) as conn:
        return conn.execute(sql, params).fetchall()


def stored(dsn: str, name: str, kind: str = "models"):
    """(skeleton_id, data) of the graph, or None."""
    rows = query(
        dsn, "SELECT skeleton_id, data FROM modb.graphs WHERE name = %s AND kind = %s", [name, kind]
    )
    return rows[0] if rows else None


def walk_graph(left: int, right: int) -> dict:
    return {
        "nodes": {
            "left_step": {"model_id": left, "type": "standard", "action": "walk"},
            "right_step": {"model_id": right, "type": "standard", "action": "walk"},
        },
        "transitions": [
            {"from": "left_step", "to": "right_step"},
            {"from": "right_step", "to": "left_step"},
        ],
    }


@pytest.fixture(scope="module")
def site(cmu16_walks):
    """CMU 16's trials with their steps found, a model of each side's steps (a copy of conftest's
    cmu16_walks, less the graph of models it made and its turning steps' models), a graph of the
    two made in SQL, a loader's and a reader's token, served."""
    with cmu16_walks(f"model_graphs_web_{os.getpid()}") as dsn:
        with psycopg.connect(dsn, autocommit=True) as conn:
            ensure_writer_role(conn)
        for args in (("model", "graph", "delete", GRAPH),
                     ("model", "delete", "walk_left_turning_step"),
                     ("model", "delete", "walk_right_turning_step")):  # fmt: skip
            r = run_modb(dsn, *args, process=False)
            assert r.returncode == 0, r.stderr
        tokens = {}
        for name, role in (("editor", "loader"), ("viewer", "reader")):
            r = run_modb(dsn, "token", "create", name, "--role", role, process=False)
            assert r.returncode == 0, r.stderr
            tokens[name] = r.stdout.strip()
        with psycopg.connect(dsn) as conn:
            models = dict(
                conn.execute(
                    "SELECT name, id FROM modb.models WHERE kind = 'motion_primitive'"
                ).fetchall()
            )
            (skeleton,) = conn.execute(
                "SELECT DISTINCT skeleton_id FROM modb.models WHERE kind = 'motion_primitive'"
            ).fetchone()
            conn.execute("INSERT INTO modb.graph_names VALUES (%s, 'models')", [GRAPH])
            (graph,) = conn.execute(
                "INSERT INTO modb.graphs (name, kind, skeleton_id, data) "
                "VALUES (%s, 'models', %s, %s) RETURNING id",
                [GRAPH, skeleton, Jsonb(walk_graph(models[LEFT], models[RIGHT]))],
            ).fetchone()
        with serving(dsn) as address:
            yield Site(address, dsn, tokens, models, skeleton, graph)


@pytest.fixture
def client(site):
    with httpx.Client(base_url=f"http://{site.address}", timeout=60) as c:
        yield c


def bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def put(client, ident: int, data, headers: dict[str, str]) -> httpx.Response:
    return client.put(f"/api/graphs/{ident}", json={"data": data}, headers=headers)


def test_rest_graphs_of_models_need_the_etag_they_were_read_with(site, client):
    editor, viewer = bearer(site.tokens["editor"]), bearer(site.tokens["viewer"])
    left, right = site.models[LEFT], site.models[RIGHT]

    # Listed by kind, with their sizes; other kinds and unknown parameters as before.
    r = client.get("/api/graphs", params={"kind": "models"})
    assert r.status_code == 200
    assert [(g["name"], g["nodes"], g["transitions"]) for g in r.json()] == [(GRAPH, 2, 2)]
    assert client.get("/api/graphs", params={"kind": "transitions"}).json() == []
    assert client.get("/api/graphs", params={"knid": "models"}).status_code == 400

    # A new graph of models: the database checks it; a broken one is refused with its reason.
    one = {"nodes": {"first": {"model_id": left, "type": "start"}}}
    broken = {"nodes": {"first": {"model_id": 999999, "type": "start"}}}
    r = client.post(
        "/api/graphs",
        json={"name": "rest", "kind": "models", "skeleton_id": site.skeleton, "data": broken},
        headers=editor,
    )
    assert r.status_code == 400, r.text
    assert 'is broken: node "first": there is no motion model with id 999999' in r.json()["error"]
    assert stored(site.dsn, "rest") is None
    assert query(site.dsn, "SELECT count(*) FROM modb.graph_names WHERE name = 'rest'") == [(0,)]
    r = client.post(
        "/api/graphs",
        json={"name": "rest", "kind": "models", "skeleton_id": site.skeleton, "data": one},
        headers=editor,
    )
    assert r.status_code == 201, r.text
    ident, made_tag = r.json()["id"], r.headers["ETag"]
    assert stored(site.dsn, "rest") == (site.skeleton, one)

    # Read: its ETag, the one the create answered.
    r = client.get(f"/api/graphs/{ident}")
    assert r.status_code == 200 and r.json()["data"] == one
    first = r.headers["ETag"]
    assert first == made_tag

    two = {
        "nodes": {**one["nodes"], "then": {"model_id": right, "type": "end"}},
        "transitions": [{"from": "first", "to": "then"}],
    }
    # No If-Match: 428; a stale one: 409 with the current ETag; neither stores anything.
    r = put(client, ident, two, editor)
    assert r.status_code == 428 and "If-Match" in r.json()["error"]
    r = put(client, ident, two, {**editor, "If-Match": '"stale"'})
    assert r.status_code == 409 and r.headers["ETag"] == first
    assert stored(site.dsn, "rest") == (site.skeleton, one)
    # A reader's token, or none, cannot write even with the right ETag.
    r = put(client, ident, two, {**viewer, "If-Match": first})
    assert r.status_code == 403
    r = put(client, ident, two, {"If-Match": first})
    assert r.status_code == 401
    assert stored(site.dsn, "rest") == (site.skeleton, one)

    # The right one: stored, and a new ETag, the one a read gives now.
    r = put(client, ident, two, {**editor, "If-Match": first})
    assert r.status_code == 200, r.text
    second = r.headers["ETag"]
    assert second != first and r.json()["etag"] == second
    assert stored(site.dsn, "rest") == (site.skeleton, two)
    assert client.get(f"/api/graphs/{ident}").headers["ETag"] == second
    # The first ETag is stale now.
    r = put(client, ident, one, {**editor, "If-Match": first})
    assert r.status_code == 409 and r.headers["ETag"] == second

    # A broken graph (a node no transition reaches) is refused with the database's reason.
    unreached = {**two, "transitions": []}
    r = put(client, ident, unreached, {**editor, "If-Match": second})
    assert r.status_code == 400
    reason = 'graph of models "rest" is broken: node "then" is reached by no transition'
    assert reason in r.json()["error"]
    assert stored(site.dsn, "rest") == (site.skeleton, two)
    assert client.get(f"/api/graphs/{ident}").headers["ETag"] == second
    assert query(
        site.dsn,
        "SELECT count(*) FROM modb.audit_log WHERE action = 'graph replace' AND object = %s",
        [f"graph {ident}"],
    ) == [(1,)]

    # Other kinds as before: no ETag, replaced without If-Match.
    r = client.post(
        "/api/graphs", json={"name": "rest", "kind": "motion", "data": {"a": 1}}, headers=editor
    )
    assert r.status_code == 201 and "ETag" not in r.headers
    other = r.json()["id"]
    assert "ETag" not in client.get(f"/api/graphs/{other}").headers
    r = client.put(f"/api/graphs/{other}", json={"data": {"a": 2}}, headers=editor)
    assert r.status_code == 200, r.text
    assert stored(site.dsn, "rest", "motion") == (None, {"a": 2})
    for ident in (ident, other):
        assert client.delete(f"/api/graphs/{ident}", headers=editor).status_code == 200


# The web view


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver, "1280,1000") as driver:
        yield driver


def wait_for(browser, script: str, timeout: float = 30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = browser.execute_script(script)
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for: {script}")


def open_page(browser, site: Site) -> None:
    browser.get(f"http://{site.address}/")
    assert (
        browser.execute_async_script(
            "const done = arguments[0]; "
            "Promise.all([window.modbViewer.ready, window.modbModelGraphs.ready])"
            ".then(() => done('ok'), (e) => done(String(e)))"
        )
        == "ok"
    )
    browser.execute_script("window.modbViewer.pause()")  # the clip's drawing costs the page's time
    browser.find_element(By.ID, "token").send_keys(site.tokens["editor"])
    browser.find_element(By.ID, "token-use").click()


def choose(browser, css: str, value) -> None:
    Select(browser.find_element(By.CSS_SELECTOR, css)).select_by_value(str(value))


def click(browser, css: str) -> None:
    element = browser.find_element(By.CSS_SELECTOR, css)
    browser.execute_script("arguments[0].scrollIntoView({block: 'center'})", element)
    element.click()


def status(browser) -> str:
    return browser.find_element(By.ID, "graph-status").text


def save(browser, expect: str) -> str:
    click(browser, "#graph-save")
    wait_for(
        browser,
        f"return document.getElementById('graph-status').textContent.startsWith({expect!r})",
    )
    return status(browser)


def drawn(browser) -> dict:
    """What the drawing shows: each node's type, each arrow's ends."""
    return browser.execute_script(
        "const d = document.getElementById('graph-drawing');"
        "return {nodes: Object.fromEntries([...d.querySelectorAll('g[data-node]')]"
        "          .map((g) => [g.dataset.node, g.dataset.type])),"
        "        arrows: [...d.querySelectorAll('path[data-from]')]"
        "          .map((p) => [p.dataset.from, p.dataset.to]).sort()};"
    )


def test_the_editor_adds_saves_is_refused_with_the_reason_and_makes_a_graph(site, browser, client):
    left, right = site.models[LEFT], site.models[RIGHT]
    assert stored(site.dsn, GRAPH) == (site.skeleton, walk_graph(left, right))
    open_page(browser, site)
    assert browser.find_element(By.ID, "graphs-panel").is_displayed()
    entry = browser.find_element(By.CSS_SELECTOR, f"#model-graphs span[data-graph='{GRAPH}']")
    assert entry.text == f"{GRAPH} · 2 nodes · 2 transitions"

    # Opened: drawn as stored, with the ETag the REST interface gives.
    entry.click()
    wait_for(browser, "return window.modbModelGraphs.etag")
    read = client.get(f"/api/graphs/{site.graph}").headers["ETag"]
    assert browser.execute_script("return window.modbModelGraphs.etag") == read
    assert drawn(browser) == {
        "nodes": {"left_step": "standard", "right_step": "standard"},
        "arrows": [["left_step", "right_step"], ["right_step", "left_step"]],
    }
    # only the models of the graph's skeleton are offered as nodes
    offered = browser.execute_script(
        "return [...document.querySelectorAll('#graph-add-model option')].map((o) => +o.value)"
    )
    assert sorted(offered) == sorted([left, right])

    # A node playing the left steps' model, marked a start node, and a transition from it.
    choose(browser, "#graph-add-model", left)
    browser.find_element(By.ID, "graph-add-name").send_keys("begin")
    click(browser, "#graph-add-node")
    choose(browser, "#graph-nodes li[data-node='begin'] select", "start")
    choose(browser, "#graph-from", "begin")
    choose(browser, "#graph-to", "right_step")
    click(browser, "#graph-add-transition")
    assert drawn(browser) == {
        "nodes": {"begin": "start", "left_step": "standard", "right_step": "standard"},
        "arrows": [
            ["begin", "right_step"],
            ["left_step", "right_step"],
            ["right_step", "left_step"],
        ],
    }
    assert stored(site.dsn, GRAPH)[1] == walk_graph(left, right)  # nothing stored before a save
    assert save(browser, "saved") == "saved"
    skeleton, data = stored(site.dsn, GRAPH)
    assert skeleton == site.skeleton
    assert data["nodes"]["begin"] == {
        "model_id": left, "model": LEFT, "version": 1, "type": "start", "action": "walk"
    }  # fmt: skip
    assert data["nodes"]["left_step"] == walk_graph(left, right)["nodes"]["left_step"]
    assert sorted((t["from"], t["to"]) for t in data["transitions"]) == [
        ("begin", "right_step"), ("left_step", "right_step"), ("right_step", "left_step")
    ]  # fmt: skip
    saved_tag = browser.execute_script("return window.modbModelGraphs.etag")
    assert saved_tag == client.get(f"/api/graphs/{site.graph}").headers["ETag"]

    # The only transition into left_step removed: the database refuses the graph, the page says why.
    click(browser, "#graph-transitions li[data-from='right_step'][data-to='left_step'] button")
    said = save(browser, "not saved")
    assert 'graph of models "walk" is broken: node "left_step" is reached by no transition' in said
    assert "error" in browser.find_element(By.ID, "graph-status").get_attribute("class")
    assert stored(site.dsn, GRAPH) == (skeleton, data)  # unchanged
    assert browser.execute_script("return window.modbModelGraphs.dirty") is True

    # Back to the stored graph; the added node removed, with its transition, and saved.
    click(browser, "#graph-revert")
    wait_for(browser, "return !window.modbModelGraphs.dirty")
    assert browser.execute_script("return window.modbModelGraphs.data") == data
    click(browser, "#graph-nodes li[data-node='begin'] button")
    assert sorted(drawn(browser)["nodes"]) == ["left_step", "right_step"]
    assert save(browser, "saved") == "saved"
    assert stored(site.dsn, GRAPH) == (site.skeleton, walk_graph(left, right))
    assert browser.find_element(By.CSS_SELECTOR, f"span[data-graph='{GRAPH}']").text == (
        f"{GRAPH} · 2 nodes · 2 transitions"
    )

    # A new graph from the page: one start node playing the chosen model, on its skeleton.
    browser.find_element(By.ID, "graph-new-name").send_keys("fresh")
    choose(browser, "#graph-new-model", right)
    click(browser, "#graph-create")
    wait_for(browser, "return window.modbModelGraphs.opened?.name === 'fresh'")
    assert stored(site.dsn, "fresh") == (
        site.skeleton,
        {
            "nodes": {
                "right_step": {"model_id": right, "model": RIGHT, "version": 1, "type": "start"}
            },
            "transitions": [],
        },
    )
    assert drawn(browser) == {"nodes": {"right_step": "start"}, "arrows": []}

    # The refused save's 400 is the only error the console shows.
    errors = [e["message"] for e in severe_console_entries(browser)]
    assert all(f"/api/graphs/{site.graph}" in m and "400" in m for m in errors), errors
