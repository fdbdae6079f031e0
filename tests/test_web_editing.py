"""The web view's write side in headless Chromium (issue 25): the token pasted once (session
storage, never a cookie or URL), uploads by the file chooser with each file's result, and the
timeline annotation editor's operations by keyboard, saved through the REST interface and read back
from the database; a save over someone else's newer edit is refused."""

from __future__ import annotations

import os
import shutil
import time

import psycopg
import pytest
from selenium.webdriver import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from support.browser import module_page, serving, severe_console_entries
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database
from support.snippet_oracle import motion_world

from modb.database.cluster import ensure_writer_role


@pytest.fixture(scope="module")
def site(cluster):
    """A database with one walk served, and a loader token; (address, dsn, token)."""
    with scratch_database(cluster, f"editing_{os.getpid()}") as dsn:
        with psycopg.connect(dsn, autocommit=True) as conn:
            ensure_writer_role(conn)
        walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_005.bvh")
        assert run_modb(dsn, "load", walk, "--collection", "web/loaded", "-q").returncode == 0
        r = run_modb(dsn, "token", "create", "browser", "--role", "loader")
        assert r.returncode == 0, r.stderr
        with serving(dsn) as address:
            yield address, dsn, r.stdout.strip()


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver) as driver:
        yield driver


def wait_for(browser, script: str, timeout: float = 60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = browser.execute_script(script)
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for: {script}")


def open_page(browser, address: str, query: str = "") -> None:
    browser.get(f"http://{address}/{query}")
    assert (
        browser.execute_async_script(
            "const done = arguments[0]; "
            "window.modbViewer.ready.then(() => done('ok'), (e) => done(String(e)))"
        )
        == "ok"
    )


def use_token(browser, token: str) -> None:
    browser.find_element(By.ID, "token").send_keys(token)
    browser.find_element(By.ID, "token-use").click()


def stored_segments(dsn: str, clip: int) -> list[tuple[str, int, int]]:
    with psycopg.connect(dsn) as conn:
        (meta,) = conn.execute(
            "SELECT meta FROM modb.clip_versions WHERE clip_id = %s ORDER BY version DESC LIMIT 1",
            [clip],
        ).fetchone()
    return sorted((a["start"], a["end"], a["name"]) for a in meta.get("annotations", []))


def test_upload_by_the_file_chooser_reports_each_file(site, browser, tmp_path):
    address, dsn, token = site
    good = mocap("bandai-2-dev", "data", "dataset-2_walk_active_003.bvh")
    lines = good.read_text().splitlines()
    frame = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 3
    lines[frame] = "1 2 three"
    bad = tmp_path / "cut_short.bvh"
    bad.write_text("\n".join(lines) + "\n")
    copy = tmp_path / good.name
    shutil.copy(good, copy)
    open_page(browser, address)
    use_token(browser, token)
    assert browser.execute_script("return document.cookie") == ""
    browser.find_element(By.ID, "upload-collection").clear()
    browser.find_element(By.ID, "upload-collection").send_keys("web/uploads")
    chooser = browser.find_element(By.ID, "upload-files")
    chooser.send_keys(f"{copy}\n{bad}")
    rows = wait_for(
        browser,
        "const r = [...document.querySelectorAll('#uploads li')]; "
        "return r.length === 2 && r.every((li) => li.dataset.status) && "
        "r.map((li) => [li.querySelector('span').textContent, li.dataset.status, "
        "li.querySelector('.result').textContent]);",
    )
    by_name = {name: (status, text) for name, status, text in rows}
    assert by_name[good.name][0] == "loaded"
    assert by_name["cut_short.bvh"][0] == "failed"
    assert by_name["cut_short.bvh"][1].startswith(f"cut_short.bvh:{frame + 1}:")
    with psycopg.connect(dsn) as conn:
        names = [r[0] for r in conn.execute("SELECT name FROM modb.current_clips").fetchall()]
    assert good.stem in names and "cut_short" not in names
    # the uploaded clip opens and plays
    wait_for(browser, f"return window.modbViewer.state.clip?.name === '{good.stem}'")
    # the bad file's 400 is the only error the console shows
    errors = [e["message"] for e in severe_console_entries(browser)]
    assert all("/api/uploads" in m and "400" in m for m in errors), errors


def test_the_editor_adds_moves_cuts_merges_renames_deletes_and_saves(site, browser):
    """The issue's must-show: a BVH uploaded over HTTP with a token, a segment added, moved and cut
    in the browser, the stored annotations read back in SQL, a selection keeping to them."""
    import httpx

    address, dsn, token = site
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_007.bvh")
    r = httpx.post(
        f"http://{address}/api/uploads",
        data={"collection": "web/uploaded"},
        files=[("file", (walk.name, walk.read_bytes(), "application/octet-stream"))],
        headers={"Authorization": f"Bearer {token}"},
        timeout=120,
    )
    assert r.status_code == 200, r.text
    clip = r.json()["results"][0]["clip_id"]
    with psycopg.connect(dsn) as conn:
        (n,) = conn.execute(
            "SELECT n_frames FROM modb.current_clips WHERE clip_id = %s", [clip]
        ).fetchone()
    open_page(browser, address, f"?clip={clip}")
    wait_for(browser, "return window.modbViewer.editor.etag")
    if not browser.execute_script("return sessionStorage.getItem('modb-token')"):
        use_token(browser, token)
    keys = ActionChains(browser)

    def at(frame: int, *pressed: str) -> None:
        browser.execute_script(f"window.modbViewer.pause(); window.modbViewer.setFrame({frame})")
        browser.find_element(By.ID, "view").click()  # keys go to the page, not a field
        browser.execute_script(f"window.modbViewer.pause(); window.modbViewer.setFrame({frame})")
        for key in pressed:
            keys.send_keys(key).perform()

    name = browser.find_element(By.ID, "segment-name")
    name.clear()
    name.send_keys("stride")
    at(10, "n")  # new: 10-39
    at(50, "]")  # its end moves to 50
    at(30, "c", "s")  # cut: 10-29 and 30-50, saved
    wait_for(browser, "return document.getElementById('annotation-status').textContent === 'saved'")
    assert stored_segments(dsn, clip) == [(10, 29, "stride"), (30, 50, "stride")]
    at(70, "n")  # another: 70-99
    # select the first (Tab from the last selected wraps to it) and merge it with the next
    browser.execute_script("window.modbViewer.editor.select(0)")
    at(10, "m")  # 10-50 again
    browser.execute_script("window.modbViewer.editor.select(1)")
    name.clear()
    name.send_keys("turn\n")  # rename 70-99
    browser.execute_script("window.modbViewer.editor.select(0)")
    at(20, "[")  # start of 10-50 moves to 20
    tags = browser.find_element(By.ID, "tags")
    tags.clear()
    tags.send_keys("walk, web\n")
    at(20, "s")
    wait_for(browser, "return document.getElementById('annotation-status').textContent === 'saved'")
    assert stored_segments(dsn, clip) == [(20, 50, "stride"), (70, 99, "turn")]
    with psycopg.connect(dsn) as conn:
        (meta,) = conn.execute(
            "SELECT meta FROM modb.clip_versions WHERE clip_id = %s", [clip]
        ).fetchone()
        audit = conn.execute(
            "SELECT token_name, action FROM modb.audit_log ORDER BY id DESC LIMIT 1"
        ).fetchone()
    assert meta["tags"] == ["walk", "web"] and audit == ("browser", "meta")
    # the selection, in SQL, keeps to the segment just saved: every answer lies within frames 20-50
    with psycopg.connect(dsn) as conn:
        conn.execute("SET modb.annotations = 'stride'")
        (prev,) = conn.execute(
            "SELECT id FROM modb.snippets WHERE clip_id = %s ORDER BY first_frame LIMIT 1", [clip]
        ).fetchone()
        chosen = conn.execute(
            "SELECT clip_id, first_frame, n_frames "
            "FROM modb.select_next_snippets(%s, ARRAY[1.0, 0.0, 2.0], 8)",
            [prev],
        ).fetchall()
    assert chosen and all(c == clip and f >= 20 and f + n - 1 <= 50 for c, f, n in chosen), chosen
    # delete the second, save: the database holds one
    browser.execute_script("window.modbViewer.editor.select(1)")
    at(0, Keys.DELETE, "s")
    wait_for(browser, "return document.getElementById('annotation-status').textContent === 'saved'")
    assert stored_segments(dsn, clip) == [(20, 50, "stride")]
    assert n > 100


def test_a_save_over_a_newer_edit_is_refused(site, browser):
    address, dsn, token = site
    with psycopg.connect(dsn) as conn:
        (clip,) = conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'web/loaded'"
        ).fetchone()
    open_page(browser, address, f"?clip={clip}")
    wait_for(browser, "return window.modbViewer.editor.etag")
    before = stored_segments(dsn, clip)
    r = run_modb(dsn, "annotate", str(clip), "--segment", "theirs:1-5")  # someone else, meanwhile
    assert r.returncode == 0, r.stderr
    browser.execute_script("window.modbViewer.pause(); window.modbViewer.setFrame(60)")
    browser.find_element(By.ID, "view").click()
    ActionChains(browser).send_keys("n").send_keys("s").perform()
    wait_for(
        browser,
        "return document.getElementById('annotation-status').textContent.includes('someone saved')",
    )
    assert stored_segments(dsn, clip) == sorted([*before, (1, 5, "theirs")])
    # the token lives in this tab's session storage, never in the address or a cookie
    assert browser.execute_script("return sessionStorage.getItem('modb-token')") == token
    assert (
        token not in browser.current_url and browser.execute_script("return document.cookie") == ""
    )


def test_the_skeleton_panel_draws_each_joints_axes(site, browser):
    """The 'axes' box draws every mapped joint's twist and swing axes (issue 26): each segment
    starts at its joint and points along the axis turned by the joint's world rotation, by this
    test's own forward kinematics (scipy) of the frame shown."""
    import numpy as np

    from modb.clips import read_motion
    from modb.database import pgarray
    from modb.editing.retarget import prepared
    from modb_kernel.retarget import stored_form

    address, dsn, _ = site
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        (clip,) = conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'web/loaded'"
        ).fetchone()
        motion = read_motion(conn, clip)
        axes = stored_form(prepared(motion.skeleton, motion))
        conn.execute(
            "UPDATE modb.skeletons SET joint_axes = %s WHERE id = "
            "(SELECT skeleton_id FROM modb.current_clips WHERE clip_id = %s)",
            [psycopg.types.json.Jsonb(axes), clip],
        )
    open_page(browser, address, f"?clip={clip}")
    browser.execute_script("window.modbViewer.pause(); window.modbViewer.setFrame(40)")
    browser.find_element(By.ID, "show-axes").click()
    drawn = wait_for(browser, "return window.modbViewer.axes().length && window.modbViewer.axes()")
    assert len(drawn) == 2 * len(axes["joints"])
    # the tests' own forward kinematics (scipy) of frame 40
    sk = motion.skeleton
    positions, turns = motion_world(motion)
    want = []
    for a in axes["joints"].values():
        j = sk.index(a["joint"])
        for v in (a["twist"], a["swing"]):
            want.append((positions[40, j], positions[40, j] + 0.12 * turns[j][40].apply(v)))
    # jsonb keeps its own key order: compare as sets of segments
    got = sorted(tuple(np.round(np.concatenate([s, e]), 4)) for s, e, _ in drawn)
    wanted = sorted(tuple(np.round(np.concatenate([s, e]), 4)) for s, e in want)
    assert np.abs(np.array(got) - np.array(wanted)).max() < 2e-4
    browser.find_element(By.ID, "show-axes").click()
    assert browser.execute_script("return window.modbViewer.stageAxesShown()") is False


def test_a_dropped_file_is_uploaded(site, browser):
    """Drag and drop: a drop event carrying a BVH file (as the browser makes one) uploads it."""
    import base64

    address, dsn, token = site
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_009.bvh")
    open_page(browser, address)
    if not browser.execute_script("return sessionStorage.getItem('modb-token')"):
        use_token(browser, token)
    browser.find_element(By.ID, "upload-collection").clear()
    browser.find_element(By.ID, "upload-collection").send_keys("web/dropped")
    browser.execute_script(
        "const bytes = Uint8Array.from(atob(arguments[0]), (c) => c.charCodeAt(0));"
        "const data = new DataTransfer();"
        "data.items.add(new File([bytes], arguments[1]));"
        "document.getElementById('drop').dispatchEvent("
        "  new DragEvent('drop', {dataTransfer: data, bubbles: true, cancelable: true}));",
        base64.b64encode(walk.read_bytes()).decode(),
        walk.name,
    )
    wait_for(
        browser,
        "return [...document.querySelectorAll('#uploads li')].some((li) => "
        f"li.querySelector('span').textContent === '{walk.name}' "
        "&& li.dataset.status === 'loaded')",
    )
    with psycopg.connect(dsn) as conn:
        assert (
            conn.execute(
                "SELECT count(*) FROM modb.current_clips "
                "WHERE collection = 'web/dropped' AND name = %s",
                [walk.stem],
            ).fetchone()[0]
            == 1
        )


def test_the_plot_shows_a_joints_height_speed_and_world_x_and_z(site, browser):
    """The editor's plot: the chosen joint's height and horizontal speed in every frame, against
    this test's own forward kinematics (scipy) and numpy's gradient."""
    import numpy as np

    from modb.clips import read_motion
    from modb.database import pgarray

    address, dsn, _ = site
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        (clip,) = conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE collection = 'web/loaded'"
        ).fetchone()
        motion = read_motion(conn, clip)
    open_page(browser, address, f"?clip={clip}")
    wait_for(browser, "return window.modbViewer.editor.plotValues()")
    sk = motion.skeleton
    ankle = sk.index(sk.joint_map["left_ankle"])
    p = motion_world(motion)[0]
    for quantity, want in (
        ("height", p[:, ankle, 1]),
        ("speed", np.hypot(*np.gradient(p[:, ankle][:, [0, 2]], axis=0).T) * motion.fps),
        ("x", p[:, ankle, 0]),
        ("z", p[:, ankle, 2]),
    ):
        browser.execute_script(
            "document.getElementById('plot-joint').value = arguments[0];"
            "document.getElementById('plot-quantity').value = arguments[1];"
            "['plot-joint', 'plot-quantity'].forEach((id) => document.getElementById(id)"
            "  .dispatchEvent(new Event('change')));",
            str(ankle),
            quantity,
        )
        got = np.array(browser.execute_script("return window.modbViewer.editor.plotValues()"))
        assert got.shape == want.shape and np.abs(got - want).max() < 1e-4, quantity
