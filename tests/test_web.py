"""`modb serve`: the JSON endpoints and the page in a real browser (Debian's chromium via
chromium-driver), against the real server and a database of real capture (a Bandai BVH clip and a
CMU ASF/AMC clip)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

import numpy as np
import psycopg
import pytest
from support.asf_oracle import bone_tips, parse_amc, parse_asf
from support.browser import module_page, get, serving, severe_console_entries
from support.bvh_oracle import bvhio_world_positions, in_order
from support.commands import run_modb
from support.data import CMU_UNITS, REPO, mocap
from support.databases import scratch_database

TOLERANCE_M = 0.01  # the bar for the page against the server
ARTIFACTS = REPO / "tests" / "artifacts"
BVH_FILE = ("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
BANDAI_1_FILE = "dataset-1_bow_active_001.bvh"
KINDS = ["bvh", "bandai1", "cmubvh", "amc", "amc01"]


def sources(tmp: Path) -> list[tuple[Path, str, str]]:
    """(file or folder, collection, --units): one clip of each skeleton kind in the shared data."""
    out = [
        (mocap(*BVH_FILE), "web/bvh", "auto"),
        (mocap("bandai-1", "data", BANDAI_1_FILE), "web/bandai1", "auto"),
        (mocap("cmu", "131", "bvh", "131_01.bvh"), "web/cmubvh", repr(CMU_UNITS)),
    ]
    for folder, asf, amc, collection in (
        ("131", "131.asf", "131_01.amc", "web/amc"),
        ("01", "01.asf", "01_01.amc", "web/amc01"),
    ):
        (tmp / folder).mkdir()
        for name in (asf, amc):
            shutil.copy(mocap("cmu", folder, name), tmp / folder / name)
        out.append((tmp / folder, collection, repr(CMU_UNITS)))
    return out


@pytest.fixture(scope="module")
def web_db(cluster, tmp_path_factory):
    """One clip per collection web/<kind>: Bandai dataset 2 and 1 BVH, a CMU BVH conversion, CMU
    ASF/AMC (131 and 01)."""
    with scratch_database(cluster, f"web_{os.getpid()}") as dsn:
        for path, collection, units in sources(tmp_path_factory.mktemp("sources")):
            r = run_modb(dsn, "load", path, "--collection", collection, "--units", units, "-q")
            assert r.returncode == 0, r.stderr
        graph = "graph build web --collection web/amc --profile locomotion --min-turn 0 -q"
        r = run_modb(dsn, *graph.split())
        assert r.returncode == 0, r.stderr
        with psycopg.connect(dsn, autocommit=True) as conn:  # nothing writes models yet: by hand
            conn.execute(
                "INSERT INTO modb.models (name, kind, data) "
                "VALUES ('gait', 'pca', '{\"components\": 3}')"
            )
        yield dsn


@pytest.fixture(scope="module")
def server(web_db):
    """The real `modb serve` on a free port; (host:port, dsn)."""
    with serving(web_db) as address:
        yield address, web_db


def ok(address: str, path: str):
    status, body = get(address, path)
    assert status == 200, body
    return body


def clip_ids(address: str) -> dict[str, int]:
    """{kind: clip id} (KINDS) from the endpoints themselves."""
    out = {}
    for c in ok(address, "/api/collections"):
        if c["path"].startswith("web/"):
            (clip,) = ok(address, f"/api/clips?collection={c['id']}")
            out[c["path"][4:]] = clip["id"]
    return out


# --- JSON endpoints -------------------------------------------------------------------------------


def test_the_endpoints_list_what_the_database_holds(server):
    address, dsn = server
    paths = {c["path"]: c for c in ok(address, "/api/collections")}
    assert {"web", *(f"web/{k}" for k in KINDS)} <= set(paths)
    assert paths["web"]["clips"] == 0 and paths["web/bvh"]["parent_id"] == paths["web"]["id"]
    ids = clip_ids(address)
    everything = ok(address, "/api/clips")
    assert sorted(c["id"] for c in everything) == sorted(ids.values())
    amc = ok(address, f"/api/clips/{ids['amc']}")
    assert amc["name"] == "131_01" and amc["collection"] == "web/amc" and len(amc["versions"]) == 1
    skeleton = ok(address, f"/api/skeletons/{amc['skeleton_id']}")
    assert skeleton["hierarchy"]["format"] == "asf" and skeleton["joint_map"]["pelvis"] == "root"
    assert {s["id"] for s in ok(address, "/api/skeletons")} == {
        ok(address, f"/api/clips/{i}")["skeleton_id"] for i in ids.values()
    }
    (model,) = ok(address, "/api/models")
    assert (model["name"], model["kind"]) == ("gait", "pca")
    assert "data" not in model  # listings stay small
    assert ok(address, f"/api/models/{model['id']}")["data"] == {"components": 3}
    with psycopg.connect(dsn) as conn:
        graph_id, kept = conn.execute(
            "SELECT g.id, count(s.*) FROM modb.graphs g JOIN modb.graph_snippets s "
            "ON s.graph_id = g.id GROUP BY g.id"
        ).fetchone()
    (listed,) = ok(address, "/api/graphs")
    assert (listed["id"], listed["name"], listed["kept_snippets"]) == (graph_id, "web", kept)
    assert kept > 0
    one = ok(address, f"/api/graphs/{graph_id}")
    assert one["kept_snippets"] == kept and one["data"]["kept"] == kept


def test_frames_carry_world_positions_that_independent_readers_agree_with(server):
    address, _ = server
    ids = clip_ids(address)
    # BVH: bvhio (PyPI) reads the same file.
    page = ok(address, f"/api/clips/{ids['bvh']}/frames?start=5&count=40")
    assert page["start"] == 5 and page["count"] == 40 and len(page["positions"]) == 40
    skeleton_id = ok(address, f"/api/clips/{ids['bvh']}")["skeleton_id"]
    unit_m = ok(address, f"/api/skeletons/{skeleton_id}")["hierarchy"]["unit_m"]
    names, expected = bvhio_world_positions(str(mocap(*BVH_FILE)), unit_m)
    served = in_order(page["joints"], names, np.array(page["positions"]))
    assert np.abs(served - expected[5:45]).max() < 1e-4
    # ASF/AMC: the test suite's own reader; a joint sits at its parent bone's tip.
    page = ok(address, f"/api/clips/{ids['amc']}/frames?count=30")
    tips, parent = bone_tips(
        parse_asf(str(mocap("cmu", "131", "131.asf"))),
        parse_amc(str(mocap("cmu", "131", "131_01.amc"))),
    )
    served = np.array(page["positions"])
    for k, name in enumerate(page["joints"]):
        reference = tips["root"] if name == "root" else tips[parent[name]]
        assert np.abs(served[:, k] - reference[:30]).max() < 1e-4, name


@pytest.mark.parametrize(
    "path,message",
    [
        ("/api/clips/987654", "no clip with id 987654"),
        ("/api/clips/987654/frames", "no clip with id 987654"),
        ("/api/clips/{amc}/frames?version=7", "clip {amc} has no version 7"),
        ("/api/skeletons/987654", "no skeleton with id 987654"),
        ("/api/models/987654", "no model with id 987654"),
        ("/api/graphs/987654", "no graph with id 987654"),
        ("/api/clips?collection=987654", "no collection with id 987654"),
        ("/api/nothing-here", "no such page: /api/nothing-here"),
    ],
)
def test_unknown_ids_get_404_with_a_message(server, path, message):
    ids = clip_ids(server[0])
    status, body = get(server[0], path.format(**ids))
    assert (status, body) == (404, {"error": message.format(**ids)})


@pytest.mark.parametrize(
    "query,message",
    [
        ("/api/clips/abc", "clip id must be an integer, got 'abc'"),
        ("/api/clips/{amc}/frames?count=0", "count must be 1-20000, got 0"),
        ("/api/clips/{amc}/frames?start=-1", "start must be 0 or more, got -1"),
        ("/api/clips/{amc}/frames?start=99999", "start 99999 is past the clip's last frame"),
        ("/api/clips/{amc}/frames?version=x", "version must be an integer, got 'x'"),
        ("/api/clips/{amc}/frames?frame=3", "unknown parameter 'frame'"),
        ("/api/clips?collection=web", "collection must be an integer, got 'web'"),
        ("/api/clips/1_0", "clip id must be an integer, got '1_0'"),
        ("/api/clips?collection=1&collection=2", "parameter 'collection' is given more than once"),
        ("/api/collections?all=1", "unknown parameter 'all': /api/collections takes no parameters"),
    ],
)
def test_bad_parameters_get_400_with_a_message(server, query, message):
    status, body = get(server[0], query.format(**clip_ids(server[0])))
    assert status == 400 and body["error"].startswith(message), body
    assert "Traceback" not in json.dumps(body)


@pytest.mark.parametrize(
    "headers",
    [
        # another site's page calling the API from the user's browser
        {"Origin": "http://evil.example"},
        {"Origin": "null"},  # a sandboxed or file:// page
        {"Host": "evil.example:80"},  # DNS rebinding: another name resolving to 127.0.0.1
    ],
)
def test_another_origin_or_host_is_refused(server, headers):
    address = server[0]
    for path in (
        "/api/collections",
        "/",
        "/static/viewer.js",
        "/vendor/three/build/three.module.js",
    ):
        status, body = get(address, path, headers)
        refused = "refused" in body["error"] or "is not this server" in body["error"]
        assert status == 403 and refused, (path, body)
    own_page = {"Origin": f"http://{address}"}
    assert get(address, "/api/collections", own_page)[0] == 200  # its own page may


def _external_addresses() -> list[str]:
    """This machine's IPv4 addresses other than loopback."""
    try:
        names = socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)
    except socket.gaierror:
        names = []
    listed = subprocess.run(["hostname", "-I"], capture_output=True, text=True).stdout.split()
    found = {a[4][0] for a in names} | set(listed)
    return sorted(a for a in found if "." in a and not a.startswith("127."))


def test_by_default_it_listens_on_loopback_only(server):
    port = int(server[0].rsplit(":", 1)[1])
    addresses = _external_addresses()
    if not addresses:
        pytest.skip("this machine has no address but loopback to try")
    for address in addresses:
        with socket.socket() as s:
            s.settimeout(2)
            assert s.connect_ex((address, port)) != 0, f"modb serve answered on {address}"


# --- the page in a real browser -------------------------------------------------------------------


@pytest.fixture(scope="module")
def browser(chromium_driver):
    # every frame drawn: these tests watch a clip play frame by frame
    with module_page(chromium_driver, few_frames=False) as driver:
        yield driver


def open_page(browser, address: str, query: str = "") -> None:
    browser.get(f"http://{address}/{query}")
    result = browser.execute_async_script(
        "const done = arguments[0]; "
        "window.modbViewer.ready.then(() => done('ok'), (e) => done(String(e)))"
    )
    assert result == "ok"


def test_the_page_loads_and_browses_collections_and_clips_without_console_errors(server, browser):
    from selenium.webdriver.common.by import By

    address = server[0]
    open_page(browser, address)
    tree = browser.find_element(By.ID, "collections")
    labels = [e.text for e in tree.find_elements(By.CSS_SELECTOR, "li > span")]
    assert "web (0)" in labels and "bvh (1)" in labels and "amc (1)" in labels
    # The page opens on the first clip (web/amc's); browse to another collection's.
    wanted = ok(address, f"/api/clips/{clip_ids(address)['bvh']}")
    root = ok(address, f"/api/skeletons/{wanted['skeleton_id']}")["hierarchy"]["joints"][0]["name"]
    next(e for e in tree.find_elements(By.CSS_SELECTOR, "li > span") if e.text == "bvh (1)").click()
    clip = None
    for _ in range(50):  # the list arrives with the next fetch
        items = browser.find_elements(By.CSS_SELECTOR, "#clips li > span")
        if items and items[0].text == wanted["name"]:
            clip = items[0]
            break
        time.sleep(0.1)
    assert clip is not None, [e.text for e in browser.find_elements(By.CSS_SELECTOR, "#clips span")]
    clip.click()
    shown = "return window.modbViewer.state.clip && window.modbViewer.state.clip.name"
    for _ in range(100):
        if browser.execute_script(shown) == wanted["name"]:
            break
        time.sleep(0.1)
    assert browser.execute_script(shown) == wanted["name"]
    skeleton = browser.find_element(By.ID, "skeleton")
    assert skeleton.find_elements(By.CSS_SELECTOR, "li > span")[0].text == root
    assert severe_console_entries(browser) == []


def page_pose(browser) -> tuple[int, np.ndarray, np.ndarray]:
    """The frame shown, and what the three.js scene draws for it (joint sphere centres, bone line
    ends), read back from the scene's buffers in one step."""
    read = "const v = window.modbViewer; return [v.state.frame, v.drawn()];"
    frame, drawn = browser.execute_script(read)
    return frame, np.array(drawn["joints"]), np.array(drawn["boneEnds"])


def selected_in_panels(browser) -> list[str]:
    """The entries marked selected in the side panels, top to bottom."""
    return browser.execute_script(
        "return [...document.querySelectorAll('aside span.selected')].map((s) => s.textContent)"
    )


def above_pelvis(skeleton: dict) -> set[int]:
    """The pelvis's ancestors: frames of reference the page draws no bone to (Bandai's
    joint_Root)."""
    joints = skeleton["hierarchy"]["joints"]
    k = joints[[j["name"] for j in joints].index(skeleton["joint_map"]["pelvis"])]["parent"]
    out = set()
    while k >= 0:
        out.add(k)
        k = joints[k]["parent"]
    return out


def assert_drawn_like(
    served: np.ndarray, joints: np.ndarray, bone_ends: np.ndarray, skeleton: dict
) -> None:
    assert np.abs(joints - served).max() < TOLERANCE_M
    drawn = bone_ends.reshape(-1, 2, 3)
    joints_of = skeleton["hierarchy"]["joints"]
    pelvis = [j["name"] for j in joints_of].index(skeleton["joint_map"]["pelvis"])
    hidden = above_pelvis(skeleton) | {pelvis}
    for k, joint in enumerate(joints_of):  # a line from each joint's parent to it
        if joint["parent"] >= 0 and k not in hidden:
            expected = np.stack([served[joint["parent"]], served[k]])
            assert np.abs(drawn - expected).max(axis=(1, 2)).min() < TOLERANCE_M, joint["name"]


@pytest.mark.parametrize("kind", KINDS)
def test_a_clip_plays_and_its_bones_match_the_servers_kinematics(server, browser, kind):
    address = server[0]
    clip_id = clip_ids(address)[kind]
    info = ok(address, f"/api/clips/{clip_id}")
    skeleton = ok(address, f"/api/skeletons/{info['skeleton_id']}")
    served = np.array(ok(address, f"/api/clips/{clip_id}/frames")["positions"])
    open_page(browser, address, f"?clip={clip_id}")
    browser.execute_script("window.modbViewer.play()")
    seen: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    started = time.monotonic()
    first = None
    while len(seen) < 8 and time.monotonic() - started < 20:
        frame, joints, bone_ends = page_pose(browser)
        first = first or (frame, time.monotonic())
        seen[frame] = (joints, bone_ends)
        time.sleep(0.05)
    last = (frame, time.monotonic())
    browser.execute_script("window.modbViewer.pause()")
    assert len(seen) >= 8, f"the clip did not play: frames seen {sorted(seen)}"
    for frame, (joints, bone_ends) in seen.items():
        assert_drawn_like(served[frame], joints, bone_ends, skeleton)
    frames = sorted(seen)
    moved = [np.abs(seen[a][0] - seen[b][0]).max() for a, b in zip(frames, frames[1:])]
    assert min(moved) > 1e-4  # it moves
    # At the clip's own rate, by this test's clock: never ahead (a frame per screen refresh would
    # be, at 30 fps).
    most = (last[1] - first[1] + 0.1) * info["fps"] + 2
    assert last[0] - first[0] <= most, (first, last, info["fps"])
    # Opened by address, the panels show where it is.
    assert selected_in_panels(browser) == [kind + " (1)", info["name"]]
    ARTIFACTS.mkdir(exist_ok=True)
    browser.save_screenshot(str(ARTIFACTS / f"web-view-{kind}.png"))
    assert severe_console_entries(browser) == []


def test_frame_stepping_and_the_selected_joint(server, browser):
    from selenium.webdriver.common.by import By

    address = server[0]
    clip_id = clip_ids(address)["bvh"]
    served = np.array(ok(address, f"/api/clips/{clip_id}/frames?count=3")["positions"])
    open_page(browser, address, f"?clip={clip_id}")
    # It opens playing: stop on the first frame.
    browser.execute_script("window.modbViewer.pause(); window.modbViewer.setFrame(0)")
    browser.find_element(By.ID, "next").click()
    browser.find_element(By.ID, "next").click()
    browser.find_element(By.ID, "prev").click()
    frame, joints, _ = page_pose(browser)
    assert frame == 1 and np.abs(joints - served[1]).max() < TOLERANCE_M
    joints = browser.find_element(By.ID, "skeleton").find_elements(By.CSS_SELECTOR, "li > span")
    chosen = joints[5]
    chosen.click()
    index = browser.execute_script("return window.modbViewer.state.highlighted")
    names = browser.execute_script("return window.modbViewer.jointNames()")
    assert names[index] == chosen.text and "selected" in chosen.get_attribute("class")
    marker = browser.execute_script("return window.modbViewer.stage.highlight.position.toArray()")
    assert np.abs(np.array(marker) - served[1][index]).max() < TOLERANCE_M


# --- what the page opens on -----------------------------------------------------------------------


def first_clip(address: str) -> dict:
    """The clip the page opens on without one in its address: the first collection in the listing's
    order that holds clips, and the first of its clips in the clip list's order."""
    collection = next(c for c in ok(address, "/api/collections") if c["clips"] > 0)
    return ok(address, f"/api/clips?collection={collection['id']}")[0]


def assert_plays(browser, address: str, clip: dict, seconds: float = 2.0) -> None:
    """Untouched for `seconds` of real time, the page plays `clip`: the frame shown advances at
    about the clip's rate, and what the scene draws moves and is the server's pose of the frame
    shown."""
    info = ok(address, f"/api/clips/{clip['id']}")
    served = np.array(ok(address, f"/api/clips/{clip['id']}/frames")["positions"])
    skeleton = ok(address, f"/api/skeletons/{info['skeleton_id']}")
    state = "const s = window.modbViewer.state; return [s.clip && s.clip.id, s.playing];"
    assert browser.execute_script(state) == [clip["id"], True]
    samples = []  # (time, frame, joints drawn, bone ends drawn)
    started = time.monotonic()
    deadline = started + 20
    while (
        len(samples) < 8 or time.monotonic() < started + seconds
    ) and time.monotonic() < deadline:
        frame, joints, bone_ends = page_pose(browser)
        samples.append((time.monotonic(), frame, joints, bone_ends))
        time.sleep(0.05)
    for _, frame, joints, bone_ends in samples:
        assert_drawn_like(served[frame], joints, bone_ends, skeleton)
    n = info["n_frames"]
    advanced = sum((b[1] - a[1]) % n for a, b in zip(samples, samples[1:]))  # a clip shorter wraps
    elapsed = samples[-1][0] - samples[0][0]
    expected = elapsed * info["fps"]
    most = expected + 0.1 * info["fps"] + 2  # never ahead of the clip's rate
    assert 0.5 * expected <= advanced <= most, (advanced, elapsed, info["fps"])
    frames = [s[1] for s in samples]
    assert len(set(frames)) >= 8, f"the clip did not play: frames seen {frames}"
    moved = [np.abs(a[2] - b[2]).max() for a, b in zip(samples, samples[1:]) if a[1] != b[1]]
    assert min(moved) > 1e-4, "the frame counter moved but the drawn skeleton did not"
    (collection,) = [c for c in ok(address, "/api/collections") if c["id"] == info["collection_id"]]
    shown = [f"{collection['name']} ({collection['clips']})", info["name"]]
    assert selected_in_panels(browser) == shown
    assert browser.current_url.endswith(f"/?clip={clip['id']}")  # reload and share open it again


def test_the_page_opens_playing_the_first_clip(server, browser):
    address = server[0]
    first = first_clip(address)
    assert first["collection"] == "web/amc" and first["name"] == "131_01"  # web holds none directly
    browser.get_log("browser")  # what earlier tests left
    open_page(browser, address)
    assert_plays(browser, address, first)
    assert severe_console_entries(browser) == []


def test_the_page_opens_playing_the_clip_in_its_address(server, browser):
    address = server[0]
    wanted = ok(address, f"/api/clips/{clip_ids(address)['bvh']}")
    assert wanted["id"] != first_clip(address)["id"]
    browser.get_log("browser")
    open_page(browser, address, f"?clip={wanted['id']}")
    assert_plays(browser, address, wanted)
    assert severe_console_entries(browser) == []


def test_an_empty_database_shows_how_to_load_data(fresh_db, browser):
    from selenium.webdriver.common.by import By

    browser.get_log("browser")
    with serving(fresh_db) as address:
        open_page(browser, address)
        empty = browser.find_element(By.ID, "empty")
        assert empty.is_displayed() and not browser.find_element(By.ID, "view").is_displayed()
        assert not browser.find_element(By.CSS_SELECTOR, "main > footer").is_displayed()
        text = empty.text
        assert "no clips" in text and "modb load path/to/" in text and "modb demo" in text, text
        assert browser.execute_script("return window.modbViewer.state.clip") is None
        assert "clip=" not in browser.current_url
        assert severe_console_entries(browser) == []
    commands = [line.split() for line in text.splitlines() if line.startswith("modb ")]
    assert {c[1] for c in commands} == {"load", "demo"}
    load_help = run_modb(fresh_db, "load", "--help").stdout  # the options shown are real ones
    assert all(o in load_help for c in commands for o in c if o.startswith("--")), commands


def test_a_clip_shows_as_a_skinned_character_and_downloads_as_bvh_and_gltf(server, browser):
    from selenium.webdriver.common.by import By

    address = server[0]
    clip_id = clip_ids(address)["bvh"]
    open_page(browser, address, f"?clip={clip_id}")
    browser.execute_script("window.modbViewer.pause(); window.modbViewer.setFrame(5)")
    shown = browser.execute_script(
        "const v = window.modbViewer; let skinned = 0; "
        "v.stage.scene.traverse((o) => { if (o.isSkinnedMesh && o.visible) skinned += 1; }); "
        "const c = v.state.character; const p = c.bones.map((b) => b.getWorldPosition("
        "  b.position.clone()).toArray()); "
        "return {skinned, bones: v.stage.bones.visible, character: p, rig: v.jointWorldPositions()}"
    )
    # the character's bones stand where the rig's joints do (both posed from the same frame)
    assert shown["skinned"] == 1 and shown["bones"] is False
    assert np.abs(np.array(shown["character"]) - np.array(shown["rig"])).max() < 1e-5
    browser.find_element(By.ID, "show-skeleton").click()
    assert browser.execute_script("return window.modbViewer.stage.bones.visible") is True
    for fmt, media in (("bvh", "text/plain"), ("glb", "model/gltf-binary")):
        link = browser.find_element(By.ID, f"download-{fmt}").get_attribute("href")
        status, headers = browser.execute_async_script(
            "const done = arguments[1]; fetch(arguments[0]).then(async (r) => "
            "done([r.status, {type: r.headers.get('content-type'), "
            "disposition: r.headers.get('content-disposition'), "
            "size: (await r.arrayBuffer()).byteLength}]))",
            link,
        )
        assert status == 200 and headers["type"].startswith(media), headers
        assert headers["disposition"].startswith("attachment;") and headers["size"] > 1000
    assert severe_console_entries(browser) == []
