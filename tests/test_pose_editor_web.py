"""The web view's pose editor (issue 64) in headless Chromium, on a Bandai walk: a hand selected by
a real click where it shows on the canvas, moved 10 cm up by a real mouse drag on the Y arrow of
three.js's TransformControls at a frame with a 0.5 s blend (an `ik` command), then turned by a drag
on one of its rings (a `rotate` command); each previewed by the server (POST /api/clips/ID/
edit-preview), saved with a loader token as a new version whose script holds the command, and read
back in SQL: the hand at the target by the tests' own forward kinematics and heading (scipy), the
joint's local rotation the command's rotation times the original, the preview within 0.1 mm of
what was stored, frames outside the blend range byte-equal. And the preview endpoint itself: the
same kernel as saving, its refusals."""

from __future__ import annotations

import math
import os
import time

import httpx
import numpy as np
import psycopg
import pytest
from scipy.spatial.transform import Rotation
from selenium.webdriver import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select
from support import own_kinematics
from support.browser import module_page, serving, severe_console_entries
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.clips import read_motion
from modb.database import pgarray
from modb.database.cluster import ensure_writer_role

WALK = ("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
HAND = "right_wrist"
BLEND = 0.5


@pytest.fixture(scope="module")
def site(cluster):
    """A database holding a Bandai walk, a loader token, `modb serve`: (address, dsn, token,
    clip)."""
    walk = mocap(*WALK)
    with scratch_database(cluster, f"pose_web_{os.getpid()}") as dsn:
        with psycopg.connect(dsn, autocommit=True) as conn:
            ensure_writer_role(conn)
        assert run_modb(dsn, "load", walk, "--collection", "pose/web", "-q").returncode == 0
        r = run_modb(dsn, "token", "create", "poser", "--role", "loader")
        assert r.returncode == 0, r.stderr
        with psycopg.connect(dsn) as conn:
            (clip,) = conn.execute("SELECT clip_id FROM modb.current_clips").fetchone()
        with serving(dsn) as address:
            yield address, dsn, r.stdout.strip(), clip


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver) as driver:
        yield driver


def motion(dsn, clip, number=None):
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        return read_motion(conn, clip, number)


def positions(m) -> np.ndarray:
    sk = m.skeleton
    return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, m.rotations,
                                          m.translations)  # fmt: skip


def heading(m, p, frame) -> float:
    """The character's heading at a frame: forward = hip axis x up, averaged over +-0.25 s."""
    sk = m.skeleton
    left, right = (sk.index(sk.joint_map[s]) for s in ("left_hip", "right_hip"))
    half = round(0.25 * m.fps)
    axis = p[max(0, frame - half) : frame + half + 1, left] - p[max(0, frame - half) : frame + half
                                                                  + 1, right]  # fmt: skip
    forward = np.cross(axis, [0.0, 1.0, 0.0])
    mean = (forward / np.linalg.norm(forward, axis=1, keepdims=True)).sum(0)
    return float(np.arctan2(mean[0], mean[2]))


def stored_script(dsn, clip) -> tuple[int, dict]:
    with psycopg.connect(dsn) as conn:
        return conn.execute(
            "SELECT version, load_params->'edit_script' FROM modb.clip_versions WHERE clip_id = %s "
            "ORDER BY version DESC LIMIT 1", [clip]).fetchone()  # fmt: skip


def untouched(n, frame, fps) -> np.ndarray:
    return np.abs(np.arange(n) - frame) >= BLEND * fps


# --- the endpoint ---------------------------------------------------------------------------------


def test_the_preview_is_what_saving_stores(site):
    address, dsn, token, clip = site
    before = motion(dsn, clip)
    script = [{"op": "ik", "joint": "left_wrist", "time": 1.5, "offset": [0.05, 0.08, 0.0],
               "before": BLEND, "after": BLEND},
              {"op": "rotate", "joint": "left_elbow", "time": 1.6, "rotation": [0.0, 0.0, 15.0],
               "before": 0.3, "after": 0.2}]  # fmt: skip
    h = {"Authorization": f"Bearer {token}"}
    with httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        r = client.post(f"/api/clips/{clip}/edit-preview", json={"commands": script})
        assert r.status_code == 200, r.text
        shown = r.json()
        assert shown["version"] == before.meta["version"] and shown["n_frames"] == before.n_frames
        assert [n["op"] for n in shown["notes"]] == ["ik", "rotate"] and shown["notes"][0]["met"]
        first, count = shown["start"], shown["count"]
        assert first == min(n["frames"][0] for n in shown["notes"])
        assert first + count - 1 == max(n["frames"][1] for n in shown["notes"])
        # refusals: a joint the skeleton's map lacks, an unknown clip, a malformed script
        bad = client.post(f"/api/clips/{clip}/edit-preview",
                          json={"commands": [{**script[0], "joint": "tail"}]})  # fmt: skip
        assert bad.status_code == 400 and bad.json()["error"].startswith('command 1: ik: "joint"')
        gone = client.post("/api/clips/999999/edit-preview", json={"commands": script})
        assert gone.status_code == 404
        bad = client.post(f"/api/clips/{clip}/edit-preview", json={"commands": []})
        assert bad.status_code == 400 and "commands" in bad.json()["error"]
        # saved: stored as a script and applied, a new version
        assert client.put("/api/edit-scripts/rest-pose", json={"commands": script},
                          headers=h).status_code == 201  # fmt: skip
        r = client.post("/api/edit-scripts/rest-pose/apply", json={"clips": [clip]}, headers=h)
        assert r.status_code == 200, r.text
    after = motion(dsn, clip)
    assert after.meta["version"] == before.meta["version"] + 1
    stored = positions(after)
    assert np.abs(stored[first : first + count] - np.array(shown["positions"])).max() < 1e-4
    rotations = np.array(shown["rotations"])
    assert np.abs(after.rotations[first : first + count] - rotations).max() < 1e-6
    still = np.ones(before.n_frames, bool)
    still[first : first + count] = False
    assert np.array_equal(after.rotations[still], before.rotations[still])


# --- the page -------------------------------------------------------------------------------------


def wait_for(driver, script: str, timeout: float = 30.0, *args):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = driver.execute_script(script, *args)
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for: {script}")


def open_clip(driver, address, clip, token) -> None:
    driver.get(f"http://{address}/?clip={clip}")
    assert driver.execute_async_script(
        "const done = arguments[0]; "
        "window.modbViewer.ready.then(() => done('ok'), (e) => done(String(e)))"
    ) == "ok"
    wait_for(driver, "return window.modbViewer.editor.etag")
    if not driver.execute_script("return sessionStorage.getItem('modb-token')"):
        driver.find_element(By.ID, "token").send_keys(token)
        driver.find_element(By.ID, "token-use").click()


def canvas(driver):
    return driver.find_element(By.CSS_SELECTOR, "#view canvas")


def screen(driver, point) -> tuple[int, int]:
    """Where a world point shows on the canvas, in pixels from its centre."""
    at = driver.execute_script("return window.modbViewer.stage.offsetOf(...arguments[0])",
                               [float(v) for v in point])
    assert at["visible"], (point, at)
    return at["x"], at["y"]


def click_joint(driver, standard: str) -> int:
    """A real click where the joint shows on the canvas; the joint's index, selected."""
    joint, at = driver.execute_script(
        "const v = window.modbViewer, s = v.state; v.pause();"
        "const j = v.jointNames().indexOf(s.jointMap[arguments[0]]);"
        "return [j, v.jointWorldPositions()[j]];", standard)  # fmt: skip
    x, y = screen(driver, at)
    ActionChains(driver).move_to_element_with_offset(canvas(driver), round(x), round(y)).click(
    ).perform()  # fmt: skip
    wait_for(driver, "return window.modbViewer.pose.selected === arguments[0]", 10, joint)
    assert driver.execute_script("return window.modbViewer.state.highlighted") == joint
    return joint


def gizmo(driver) -> dict:
    """The gizmo's place, axes (world, as columns x, y, z) and handle scale (TransformControls'
    own: its distance to the camera times 1.9 tan(fov / 2), times size / 4)."""
    return driver.execute_script(
        "const p = window.modbViewer.pose, c = window.modbViewer.stage.camera;"
        "const m = new p.proxy.matrixWorld.constructor().makeRotationFromQuaternion("
        "p.proxy.quaternion).elements;"
        "const d = p.proxy.position.distanceTo(c.position);"
        "return {at: p.proxy.position.toArray(),"
        "axes: [m.slice(0, 3), m.slice(4, 7), m.slice(8, 11)],"
        "scale: d * Math.min(1.9 * Math.tan(Math.PI * c.fov / 360) / c.zoom, 7) * p.gizmo.size / 4,"
        "eye: c.position.toArray()};")  # fmt: skip


def drag(driver, start: tuple[float, float], move: tuple[float, float], axis: str, steps=6):
    """A real mouse drag from `start` (pixels from the canvas's centre) by `move`, in steps (each a
    pointermove: the page previews as it goes); the gizmo's handle under the pointer checked."""
    chain = ActionChains(driver).move_to_element_with_offset(canvas(driver), round(start[0]),
                                                             round(start[1]))  # fmt: skip
    chain.pause(0.6).perform()  # hovered: TransformControls marks the handle under the pointer
    assert driver.execute_script("return window.modbViewer.pose.gizmo.axis") == axis
    chain = ActionChains(driver).click_and_hold().pause(0.3)
    done = (0, 0)
    for k in range(1, steps + 1):
        to = (round(move[0] * k / steps), round(move[1] * k / steps))
        chain = chain.move_by_offset(to[0] - done[0], to[1] - done[1]).pause(0.15)
        done = to
    chain.release().perform()


def lift_hand(driver, metres: float) -> None:
    """A real drag of the selected joint's Y arrow by `metres` up (from where the gizmo is now)."""
    g = gizmo(driver)
    up = np.array(g["axes"][1])
    grip = np.array(g["at"]) + 0.45 * g["scale"] * up  # on the Y arrow's picker
    x0, y0 = screen(driver, grip)
    x1, y1 = screen(driver, grip + metres * up)
    drag(driver, (x0, y0), (x1 - x0, y1 - y0), "Y")


def settled(driver) -> dict:
    """The page's script once its preview shows it: the commands and the notes shown."""
    return wait_for(
        driver,
        "const p = window.modbViewer.pose;"
        "return !p.drag && !p.inFlight && p.commands.length &&"
        " p.shownScript === JSON.stringify(p.commands) &&"
        " {commands: p.commands, notes: p.lastNotes};",
    )


def shown_positions(driver, first: int, last: int) -> np.ndarray:
    return np.array(driver.execute_script(
        "return window.modbViewer.state.frames.positions.slice(arguments[0], arguments[1] + 1)",
        first, last))  # fmt: skip


def save(driver, dsn, clip, was: int) -> dict:
    driver.find_element(By.ID, "pose-save").click()
    wait_for(driver, "return document.getElementById('pose-status').textContent"
             ".startsWith('saved')")
    version, record = stored_script(dsn, clip)
    assert version == was + 1
    return record


def at_frame(driver, seconds: float) -> int:
    frame = driver.execute_script(
        "const v = window.modbViewer; v.pause(); const f = Math.round(arguments[0] * v.state.fps);"
        "v.setFrame(f); return f;", seconds)  # fmt: skip
    assert driver.find_element(By.ID, "pose-before").get_attribute("value") == str(BLEND)
    assert driver.find_element(By.ID, "pose-after").get_attribute("value") == str(BLEND)
    return frame


def test_a_hand_dragged_10_cm_by_the_gizmo_is_previewed_and_saved_at_its_target(site, browser):
    address, dsn, token, clip = site
    before = motion(dsn, clip)
    open_clip(browser, address, clip, token)
    frame = at_frame(browser, 2.0)
    hand = click_joint(browser, HAND)
    g = gizmo(browser)
    y_axis = np.array(g["axes"][1])
    assert np.allclose(y_axis, [0, 1, 0], atol=1e-9)  # the heading frame's up
    # its x and z: the character's left and forward at that frame, by the test's own heading
    facing = Rotation.from_rotvec([0.0, heading(before, positions(before), frame), 0.0])
    assert np.allclose(g["axes"][0], facing.apply([1.0, 0.0, 0.0]), atol=1e-5), g["axes"]
    assert np.allclose(g["axes"][2], facing.apply([0.0, 0.0, 1.0]), atol=1e-5), g["axes"]
    lift_hand(browser, 0.1)
    shown = settled(browser)
    (command,) = shown["commands"]
    assert command["op"] == "ik" and command["joint"] == HAND
    assert command["before"] == BLEND and command["after"] == BLEND
    assert round(command["time"] * before.fps) == frame
    offset = np.array(command["offset"])
    assert 0.09 < np.linalg.norm(offset) < 0.11 and offset[1] > 0.09, offset  # 10 cm up
    (note,) = shown["notes"]
    assert note["met"] and note["frame"] == frame
    first, last = note["frames"]
    preview = shown_positions(browser, first, last)
    assert "met (" in browser.find_element(By.ID, "pose-notes").text
    record = save(browser, dsn, clip, before.meta["version"])
    assert record["commands"] == [command] and record["notes"][0]["met"]
    after = motion(dsn, clip)
    p0, p1 = positions(before), positions(after)
    turn = Rotation.from_rotvec([0.0, heading(before, p0, frame), 0.0])
    target = p0[frame, hand] + turn.apply(offset)
    assert np.linalg.norm(p1[frame, hand] - target) < 1e-3  # the hand at the target
    assert np.abs(p1[first : last + 1] - preview).max() < 1e-4  # the preview within 0.1 mm
    still = untouched(before.n_frames, frame, before.fps)
    assert np.array_equal(after.rotations[still], before.rotations[still])
    assert np.array_equal(after.translations, before.translations)
    errors = [e["message"] for e in severe_console_entries(browser)]
    assert not errors, errors


def test_a_hand_turned_by_the_gizmo_is_the_rotation_times_the_original(site, browser):
    address, dsn, token, clip = site
    before = motion(dsn, clip)
    open_clip(browser, address, clip, token)
    frame = at_frame(browser, 3.0)
    hand = click_joint(browser, HAND)
    Select(browser.find_element(By.ID, "pose-mode")).select_by_value("turn")
    browser.execute_script("window.modbViewer.stage.render()")
    g = gizmo(browser)
    axes = np.array(g["axes"])  # the hand's parent frame
    eye = np.array(g["eye"]) - g["at"]
    eye /= np.linalg.norm(eye)
    k = int(np.argmax(np.abs(axes @ eye)))  # the ring seen most nearly face on: the easiest held
    u, v = axes[(k + 1) % 3], axes[(k + 2) % 3]
    grip = np.array(g["at"]) + 0.5 * g["scale"] * (u + v) / math.sqrt(2)  # on the ring
    # TransformControls turns by the pointer's move across the axis as seen (axis x eye), on a plane
    # facing the camera: 8 cm of it there is 8 cm times 20 / (the camera's distance) radians
    across = np.cross(axes[k], eye)
    across /= np.linalg.norm(across)
    x0, y0 = screen(browser, grip)
    x1, y1 = screen(browser, grip + 0.08 * across)
    drag(browser, (x0, y0), (x1 - x0, y1 - y0), "XYZ"[k])
    shown = settled(browser)
    (command,) = shown["commands"]
    assert command["op"] == "rotate" and command["joint"] == HAND
    assert command["before"] == BLEND and round(command["time"] * before.fps) == frame
    rotation = np.array(command["rotation"])
    assert 5.0 < np.linalg.norm(rotation) < 90.0, rotation
    assert abs(rotation[k]) > 0.99 * np.linalg.norm(rotation), rotation  # about the ring's axis
    (note,) = shown["notes"]
    first, last = note["frames"]
    preview = shown_positions(browser, first, last)
    record = save(browser, dsn, clip, before.meta["version"])
    assert record["commands"] == [command]
    after = motion(dsn, clip)
    rot = own_kinematics.rotations_of
    want = Rotation.from_rotvec(np.radians(rotation)) * rot(before.rotations[frame, hand])
    assert (rot(after.rotations[frame, hand]) * want.inv()).magnitude()[0] < 2e-4  # float4
    assert np.abs(positions(after)[first : last + 1] - preview).max() < 1e-4
    still = untouched(before.n_frames, frame, before.fps)
    assert np.array_equal(after.rotations[still], before.rotations[still])
    # the page reads the clip again: the new version, no commands
    assert browser.execute_script("return window.modbViewer.pose.commands.length") == 0
    assert browser.execute_script("return window.modbViewer.state.clip.version") == (
        after.meta["version"])  # fmt: skip


def test_undo_drops_the_last_drag_and_discard_every_one_nothing_saved(site, browser):
    address, dsn, token, clip = site
    before = motion(dsn, clip)
    open_clip(browser, address, clip, token)
    stored = shown_positions(browser, 0, before.n_frames - 1)
    frame = at_frame(browser, 1.5)
    hand = click_joint(browser, HAND)
    lift_hand(browser, 0.08)
    first = settled(browser)
    shown_first = shown_positions(browser, 0, before.n_frames - 1)
    assert np.abs(shown_first[frame, hand] - stored[frame, hand]).max() > 0.05  # it moved
    lift_hand(browser, 0.06)
    two = wait_for(browser, "const p = window.modbViewer.pose; return !p.inFlight &&"
                   " p.commands.length === 2 && p.commands")  # fmt: skip
    # the second drag moved as far as the pointer did: the view kept its place under it while the
    # notes of the first command were shown
    assert 0.05 < two[1]["offset"][1] < 0.07, two[1]
    browser.find_element(By.ID, "pose-undo").click()
    shown = settled(browser)
    assert shown["commands"] == first["commands"]
    assert np.abs(shown_positions(browser, 0, before.n_frames - 1) - shown_first).max() < 1e-9
    browser.find_element(By.ID, "pose-discard").click()
    wait_for(browser, "const p = window.modbViewer.pose;"
             "return !p.inFlight && !p.commands.length && p.shownScript === '[]'")  # fmt: skip
    assert np.abs(shown_positions(browser, 0, before.n_frames - 1) - stored).max() < 1e-9
    assert browser.find_element(By.ID, "pose-save").get_attribute("disabled")
    assert stored_script(dsn, clip)[0] == before.meta["version"]  # nothing was saved
    # the chain set beside the blend: that many joints above the hand turn
    from selenium.webdriver.common.keys import Keys

    browser.find_element(By.ID, "pose-chain").send_keys("2", Keys.TAB)
    lift_hand(browser, 0.05)
    shown = settled(browser)
    (command,) = shown["commands"]
    (note,) = shown["notes"]
    assert command["chain"] == 2 and len(note["chain"]) == 2 and note["met"], note


def test_a_preview_reads_the_clip_again_when_its_skeleton_changed(site):
    """The server keeps a clip version read for the next drag update, but never past a change of
    its rows: the skeleton's joint map edited (left and right elbows swapped), the next preview
    turns the other elbow, and the one after the map's restoring the first again."""
    from psycopg.types.json import Jsonb

    address, dsn, _, clip = site
    turn = {"op": "rotate", "joint": "left_elbow", "time": 1.0, "rotation": [0.0, 0.0, 10.0],
            "before": 0.1, "after": 0.1}  # fmt: skip

    def turned(client) -> str:
        r = client.post(f"/api/clips/{clip}/edit-preview", json={"commands": [turn]})
        assert r.status_code == 200, r.text
        return r.json()["notes"][0]["skeleton_joint"]

    with psycopg.connect(dsn, autocommit=True) as conn, httpx.Client(
        base_url=f"http://{address}", timeout=60
    ) as client:
        skeleton, joint_map = conn.execute(
            "SELECT s.id, s.joint_map FROM modb.skeletons s JOIN modb.current_clips c "
            "ON c.skeleton_id = s.id WHERE c.clip_id = %s", [clip]).fetchone()  # fmt: skip
        assert turned(client) == joint_map["left_elbow"]
        swapped = {**joint_map, "left_elbow": joint_map["right_elbow"],
                   "right_elbow": joint_map["left_elbow"]}  # fmt: skip
        try:
            conn.execute("UPDATE modb.skeletons SET joint_map = %s WHERE id = %s",
                         [Jsonb(swapped), skeleton])  # fmt: skip
            assert turned(client) == joint_map["right_elbow"]
        finally:
            conn.execute("UPDATE modb.skeletons SET joint_map = %s WHERE id = %s",
                         [Jsonb(joint_map), skeleton])  # fmt: skip
        assert turned(client) == joint_map["left_elbow"]


def test_a_preview_takes_the_pose_commands_only_and_a_bounded_number(site):
    """Other scripts are applied, not previewed; a script of more than edit_preview.MAX_COMMANDS
    commands is refused before any work."""
    from modb.web.edit_preview import MAX_COMMANDS

    address, _, _, clip = site
    turn = {"op": "rotate", "joint": "left_elbow", "time": 1.0, "rotation": [0.0, 0.0, 1.0],
            "before": 0.1, "after": 0.1}  # fmt: skip
    with httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        trim = client.post(f"/api/clips/{clip}/edit-preview",
                           json={"commands": [{"op": "trim", "start": 0, "end": 10}]})  # fmt: skip
        many = client.post(f"/api/clips/{clip}/edit-preview",
                           json={"commands": [turn] * (MAX_COMMANDS + 1)})  # fmt: skip
    assert trim.status_code == 400 and "'trim' is applied, not previewed" in trim.json()["error"]
    assert many.status_code == 400 and f"at most {MAX_COMMANDS} commands" in many.json()["error"]


def test_the_blend_range_is_chosen_on_the_timelines_plot(site, browser):
    """A shift-click on the plot left of the frame shown sets the blend's start (before), right of
    it its end (after), in seconds from the frame."""
    from selenium.webdriver.common.keys import Keys

    address, dsn, token, clip = site
    fps, n = motion(dsn, clip).fps, motion(dsn, clip).n_frames
    open_clip(browser, address, clip, token)
    frame = at_frame(browser, 3.0)
    click_joint(browser, HAND)
    plot = browser.find_element(By.ID, "plot")
    width = plot.size["width"]
    for target, field in ((frame - round(1.2 * fps), "pose-before"),
                          (frame + round(0.8 * fps), "pose-after")):  # fmt: skip
        offset = round(target / (n - 1) * width - width / 2)  # from the plot's centre
        (ActionChains(browser).key_down(Keys.SHIFT).move_to_element_with_offset(plot, offset, 0)
         .click().key_up(Keys.SHIFT).perform())  # fmt: skip
        value = float(browser.find_element(By.ID, field).get_attribute("value"))
        assert abs(value - abs(target - frame) / fps) <= 1.5 / fps * (n - 1) / width + 0.02, value

