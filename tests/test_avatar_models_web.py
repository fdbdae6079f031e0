"""The avatar page on a graph of models, in a real browser (Debian's chromium), against the real
`modb serve` and a database of CMU 16's walks and turns with left and right step models, the
graph of models GRAPH, and the snippets `modb load` makes: the avatar stands at the origin as the
page opens, in both modes; on models, clicks walk it to the goals with the step's primitive,
candidates and constraint error in the panel; the same seed and goals give the walk
modb.synthesize_from_models gives (the page's own kinematics against the test's); its walk
downloads as glTF and BVH."""

from __future__ import annotations

import base64
import os
import time

import numpy as np
import psycopg
import pytest
from support import own_kinematics
from support.bvh_oracle import bvhio_world_positions
from support.browser import module_page, serving, severe_console_entries
from support.data import REPO
from support.gltf_validator import validate
from support.reaction import (
    ahead_and_aside,
    hips_heading,
    mean_heading,
    turn_reaction,
    walks_straight,
)

from modb.database import pgarray

GRAPH = "walk"
ARRIVAL_RADIUS = 0.5  # metres: the avatar's on models, as modb.synthesize_from_models's default
ARTIFACTS = REPO / "tests" / "artifacts"
STATE = (
    "const s = window.modbAvatar.state; return {frames: s.frames, frame: s.frame, goals: s.goals, "
    "goalIndex: s.goalIndex, steps: s.steps, messages: s.messages, mode: s.mode, "
    "trail: window.modbAvatar.trail()}"
)


@pytest.fixture(scope="module")
def walks(cmu16_walks):
    """CMU 16 with snippets (motion matching), steps annotated, left and right step models and
    the graph of models GRAPH over them (a copy of conftest's cmu16_walks)."""
    with cmu16_walks(f"avatar_models_{os.getpid()}") as dsn:
        yield dsn


@pytest.fixture(scope="module")
def server(walks):
    with serving(walks) as address:
        yield address, walks


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver, "1400,1000") as driver:
        yield driver


class Rig:
    """The skeleton of GRAPH (the snippets' too: one skeleton here), with the test's own
    kinematics."""

    def __init__(self, dsn: str):
        with psycopg.connect(dsn) as conn:
            hierarchy, joint_map = conn.execute(
                "SELECT s.hierarchy, s.joint_map FROM modb.graphs g JOIN modb.skeletons s "
                "ON s.id = g.skeleton_id WHERE g.name = %s AND g.kind = 'models'",
                [GRAPH],
            ).fetchone()
        joints = hierarchy["joints"]
        self.names = [j["name"] for j in joints]
        self.parents = [j["parent"] for j in joints]
        self.offsets = [j["offset"] for j in joints]
        self.translated = hierarchy["translated"]
        self.unit_m = hierarchy["unit_m"]
        self.at = {k: self.names.index(v) for k, v in joint_map.items()}

    def fk(self, rotations, translations) -> np.ndarray:
        return own_kinematics.world_positions(
            self.parents, self.offsets, self.translated, rotations, translations
        )

    def heading(self, positions) -> float:
        """Where the hips face (0: +Z), from their world positions."""
        return float(hips_heading(np.asarray(positions), self.at["left_hip"], self.at["right_hip"]))


def open_page(driver, address: str, follow: bool = False) -> None:
    from selenium.webdriver.common.by import By

    driver.get(f"http://{address}/avatar")
    ready = driver.execute_async_script(
        "const done = arguments[0]; window.modbAvatar.ready.then(done, (e) => done(String(e)))"
    )
    assert ready is True, ready
    if not follow:  # the view stays where the test puts it, for clicks
        driver.find_element(By.ID, "follow").click()


def page_state(driver) -> dict:
    return driver.execute_script(STATE)


def wait_until(driver, condition, timeout: float, what: str) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        state = page_state(driver)
        if condition(state):
            return state
        if time.monotonic() > deadline:
            raise AssertionError(
                f"{what}: not within {timeout} s; the page has {state['frames']} frames, "
                f"{len(state['steps'])} steps, last messages {state['messages'][-3:]}"
            )
        time.sleep(0.2)


def standing_pose(driver) -> dict:
    """The rig's world positions as the page posed it (three.js), and its joint names."""
    return driver.execute_script(
        "const r = window.modbAvatar.state.rig; "
        "return {names: r.joints.map((j) => j.name), positions: r.worldPositions()}"
    )


def character_pose(driver) -> list | None:
    """The skinned character's bones' world positions (three.js), once its mesh has loaded."""
    return driver.execute_script(
        "const c = window.modbAvatar.state.character; if (!c) return null; "
        "c.mesh.updateMatrixWorld(true); "
        "return c.bones.map((b) => [12, 13, 14].map((k) => b.matrixWorld.elements[k]))"
    )


def assert_stands_at_the_origin(driver, rig: Rig, what: str, within: float = 0.01) -> None:
    """The stick skeleton and the skinned character both stand above the origin (the pelvis
    within `within` metres: an idle sways), facing +Z, in one pose (the character as soon as it
    has loaded: a user sees it, not the sticks)."""
    deadline = time.monotonic() + 30
    while (bones := character_pose(driver)) is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert bones is not None, f"{what}: the character never loaded"
    posed = standing_pose(driver)
    assert np.allclose(bones, posed["positions"], atol=0.02), (what, bones[:3],
                                                               posed["positions"][:3])  # fmt: skip
    assert posed["names"] == rig.names, what
    positions = np.asarray(posed["positions"])
    pelvis = positions[rig.at["pelvis"]]
    assert np.hypot(pelvis[0], pelvis[2]) < within, (what, pelvis)  # above the origin
    feet = [rig.at[f"{side}_{part}"] for side in ("left", "right") for part in ("ankle", "toe")]
    height = pelvis[1] - positions[feet, 1].min()
    assert 0.7 < pelvis[1] < 1.2 and 0.7 < height < 1.2, (what, pelvis, height)  # an adult's
    assert abs(rig.heading(positions)) < np.radians(5), what  # facing +Z


def choose_mode(driver, value: str) -> dict:
    """What a user does: picks the mode in the selector; the page's state once the server has
    switched and the new avatar stands."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    since = len(page_state(driver)["messages"])
    frames = page_state(driver)["frames"]
    Select(driver.find_element(By.ID, "mode")).select_by_value(value)

    def switched(s: dict) -> bool:
        answer = [m["type"] for m in s["messages"][since:] if m["type"] in ("mode", "refused")]
        # a frame of the new avatar: the mode message empties the trail, its first frame starts it
        # (a frame of the last walk may arrive between the choice and the answer)
        new_avatar = bool(answer) and (answer[-1] == "refused" or bool(s["trail"]))
        return new_avatar and s["frames"] > frames

    return wait_until(
        driver,
        switched,
        30,
        f"the mode {value!r} and its standing avatar",
    )


def click_ground(driver, x: float, z: float, waypoint: bool = False) -> None:
    """A real pointer click where the ground point (x, z) shows on the canvas."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    offset = driver.execute_script(
        "return window.modbAvatar.offsetOf(arguments[0], arguments[1])", x, z
    )
    assert offset["visible"], f"({x}, {z}) is not on the canvas: {offset}"
    canvas = driver.find_element(By.CSS_SELECTOR, "#view canvas")
    actions = ActionChains(driver).move_to_element_with_offset(
        canvas, round(offset["x"]), round(offset["y"])
    )
    if waypoint:
        actions = actions.key_down(Keys.SHIFT).click().key_up(Keys.SHIFT)
    else:
        actions = actions.click()
    actions.perform()


def closest_approach(trail: list, goal) -> float:
    points = np.asarray(trail, dtype=float).reshape(-1, 2)
    return float(np.hypot(*(points - goal).T).min()) if len(points) else np.inf


def test_the_avatar_stands_at_the_origin_as_the_page_opens_in_both_modes(server, browser):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    address, dsn = server
    rig = Rig(dsn)
    open_page(browser, address)
    state = page_state(browser)
    # motion matching: the skeleton and a standing frame came with the page's first message
    assert state["mode"] == {"models": None, "seed": None}
    assert state["frames"] >= 1 and not state["goals"], state["frames"]
    assert_stands_at_the_origin(browser, rig, "motion matching")
    options = [
        o.get_attribute("value") for o in browser.find_elements(By.CSS_SELECTOR, "#mode option")
    ]
    assert options == ["", GRAPH]
    # a click: the snippet walk starts where the avatar stood
    click_ground(browser, 0.0, 2.5)
    state = wait_until(
        browser, lambda s: any(m["type"] == "choice" for m in s["messages"]), 30, "a selection"
    )
    first = browser.execute_script("return window.modbAvatar.state.pelvisAt[0]")
    assert np.hypot(first[0], first[2]) < 1e-3, first
    # a setting of motion matching, kept while the avatar walks on models
    since = len(state["messages"])
    lead_time = browser.find_element(By.ID, "lead_time")
    lead_time.send_keys(Keys.CONTROL, "a")
    lead_time.send_keys("0.3", Keys.TAB)
    wait_until(
        browser,
        lambda s: any(m["type"] == "settings" for m in s["messages"][since:]),
        10,
        "the settings answered",
    )
    # on the graph of models: a new avatar stands at the origin, idling until a goal (the graph's
    # standing: CMU 16's captured before a start)
    state = choose_mode(browser, GRAPH)
    mode = next(m for m in reversed(state["messages"]) if m["type"] in ("mode", "refused"))
    assert mode["type"] == "mode" and mode["models"] == GRAPH and mode["seed"] == 0, mode
    assert not state["steps"] and not state["goals"]
    # the last walk's trail went; the new avatar's pelvis is its first point
    assert len(state["trail"]) == 1 and closest_approach(state["trail"], (0, 0)) < 0.01
    assert_stands_at_the_origin(browser, rig, "graph of models", within=0.1)
    first = standing_pose(browser)["positions"]
    frames = state["frames"]
    time.sleep(1.0)  # idle: frames keep coming, the body moves, the pelvis stays
    assert page_state(browser)["frames"] > frames
    assert_stands_at_the_origin(browser, rig, "graph of models, idling", within=0.1)
    assert np.abs(np.asarray(standing_pose(browser)["positions"]) - first).max() > 1e-3
    assert browser.find_element(By.ID, "model-readouts").is_displayed()
    assert not browser.find_element(By.ID, "thresholds").is_displayed()
    # an unknown graph is refused, saying so; the graph of models goes on
    since = len(page_state(browser)["messages"])
    browser.execute_script("window.modbAvatar.send({type: 'mode', models: 'nowhere', seed: 0})")
    state = wait_until(
        browser,
        lambda s: any(m["type"] == "refused" for m in s["messages"][since:]),
        10,
        "the refusal",
    )
    refused = next(m for m in state["messages"][since:] if m["type"] == "refused")
    assert 'no graph of models "nowhere"' in refused["message"], refused
    assert refused["mode"] == {"models": GRAPH, "seed": 0}
    assert browser.find_element(By.ID, "status").text == refused["message"]
    assert browser.find_element(By.ID, "mode").get_attribute("value") == GRAPH
    # back to motion matching, with its settings: it stands again
    state = choose_mode(browser, "")
    assert state["mode"] == {"models": None, "seed": None}
    mode = next(m for m in reversed(state["messages"]) if m["type"] == "mode")
    assert mode["settings"]["lead_time"] == 0.3
    assert browser.find_element(By.ID, "lead_time").get_attribute("value") == "0.3"
    assert_stands_at_the_origin(browser, rig, "motion matching again")
    assert browser.find_element(By.ID, "thresholds").is_displayed()
    assert severe_console_entries(browser) == []


def test_on_models_clicks_walk_the_avatar_to_its_goals_with_the_steps_readout(
    server, browser, tmp_path
):
    from selenium.webdriver.common.by import By

    address, dsn = server
    rig = Rig(dsn)
    open_page(browser, address)
    choose_mode(browser, GRAPH)
    # the goals in view
    browser.execute_script("window.modbAvatar.stage.look([0.5, 9, -3], [0.5, 0, 3.5])")
    click_ground(browser, 0.5, 3.0)
    click_ground(browser, 1.5, 5.0, waypoint=True)
    state = wait_until(browser, lambda s: len(s["goals"]) == 2, 10, "the goal and the waypoint")
    goals = np.asarray(state["goals"])
    assert np.abs(goals - [[0.5, 3.0], [1.5, 5.0]]).max() < 0.1, goals
    state = wait_until(
        browser,
        lambda s: closest_approach(s["trail"], goals[1]) <= ARRIVAL_RADIUS,
        40,
        "the pelvis within the arrival radius of the waypoint",
    )
    trail = np.asarray(state["trail"])
    near = [np.flatnonzero(np.hypot(*(trail - g).T) <= ARRIVAL_RADIUS) for g in goals]
    assert len(near[0]) and near[0][0] < near[1][0]  # the goal first, then the waypoint
    # The steps: left and right steps of the models, each searched, with its constraint error;
    # the panel shows the last one (read in the same script as the cells).
    steps, cells = browser.execute_script(
        "return [window.modbAvatar.state.steps, Object.fromEntries(['step', 'primitive', "
        "'step-candidates', 'error', 'error-compare'].map((id) => [id, "
        "document.getElementById(id).textContent]))]"
    )
    assert len(steps) >= 4
    assert [s["step"] for s in steps] == list(range(1, len(steps) + 1))
    models = {"left_step": "cmu16_left_step", "right_step": "cmu16_right_step",
              "left_turning_step": "walk_left_turning_step",
              "right_turning_step": "walk_right_turning_step"}  # fmt: skip
    assert all(models[s["node"]] == s["model"] for s in steps)
    assert {"left_step", "right_step"} <= {s["node"] for s in steps}
    assert all(s["candidates"] > 0 and s["n_frames"] > 0 for s in steps)
    errors = np.array([[s["error_m"], s["tree_error_m"], s["random_error_m"]] for s in steps])
    assert (errors >= 0).all() and np.median(errors[:, 0]) <= np.median(errors[:, 2])
    last = steps[-1]
    assert cells == {
        "step": f"{last['step']} (goal {last['goal']})"
        if last["goal"] is not None
        else f"{last['step']} (after the last goal)",
        "primitive": f"{last['node']} ({last['model']})",
        "step-candidates": str(last["candidates"]),
        "error": f"{100 * last['error_m']:.1f} cm",
        "error-compare": f"{100 * last['tree_error_m']:.1f} cm / "
        f"{100 * last['random_error_m']:.1f} cm",
    }
    # Once the last goal is reached it comes to rest and idles: frames keep coming, the pelvis
    # stays within 0.15 m of where it came to rest.
    state = wait_until(browser, lambda s: s["goalIndex"] == 2, 20, "the waypoint marked as served")
    time.sleep(2.5)  # the last step and the settle
    resting = page_state(browser)
    time.sleep(1.5)
    later = page_state(browser)
    assert later["frames"] > resting["frames"]  # idling: no step more, frames still
    assert len(later["steps"]) == len(resting["steps"])
    assert np.hypot(*(np.asarray(later["trail"][-1]) - resting["trail"][-1])) <= 0.15
    # The walk downloads, with root motion: glTF the Khronos validator passes, BVH whose pelvis
    # (read by bvhio) went where the page's own kinematics put it, frame by frame.
    pelvis_at = browser.execute_script("return window.modbAvatar.state.pelvisAt")
    for fmt in ("glb", "bvh"):
        since = len(page_state(browser)["messages"])
        browser.find_element(By.ID, f"download-{fmt}").click()
        state = wait_until(
            browser,
            lambda s: any(m["type"] in ("file", "refused") for m in s["messages"][since:]),
            30,
            f"the walk as {fmt}",
        )
        message = next(m for m in state["messages"][since:] if m["type"] in ("file", "refused"))
        assert message["type"] == "file" and message["name"] == f"walk.{fmt}", message
        assert message["sources"] == "cmu16: licence not recorded"
        path = tmp_path / message["name"]
        path.write_bytes(base64.b64decode(message["data"]))
        if fmt == "glb":
            issues = validate(path)
            assert issues["numErrors"] == 0, issues["messages"]
            continue
        names, positions = bvhio_world_positions(str(path), rig.unit_m)
        # it idles on while the file is made: the file holds every frame shown before and more
        assert len(positions) == round(message["seconds"] * 120) + 1 >= len(pelvis_at)
        read = positions[: len(pelvis_at), names.index(rig.names[rig.at["pelvis"]])]
        shown = np.array([pelvis_at[str(k)] for k in range(len(read))])
        assert np.abs(read - shown).max() < 2e-3
    assert severe_console_entries(browser) == []


def test_the_same_seed_and_goals_give_the_walk_synthesize_from_models_gives(server, browser):
    """Goals sent with the mode, before the walk starts, as `modb synth --models GRAPH --to ...
    --seed 5` takes them: the page's pelvis, by its own kinematics, within 1 mm of the SQL
    function's strip by the test's; each step as the function reports it. The docs' picture
    (docs/avatar-models.png, copied from tests/artifacts) is taken on the way, at full density."""
    address, dsn = server
    rig = Rig(dsn)
    goals, seed = [[0.0, 3.0], [-1.5, 5.0], [0.5, 6.5]], 5
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        with conn.cursor(binary=True) as cur:
            fps, rotations, translations, report = cur.execute(
                "SELECT fps, rotations, translations, report "
                "FROM modb.synthesize_from_models(%s, %s::float8[], 30, %s)",
                [GRAPH, goals, seed],
            ).fetchone()
    assert list(report["reached"]) == ["1", "2", "3"], report["notes"]
    walked = [s for s in report["steps"] if not s.get("rest")]
    stood = walked[-1]["first_frame"] + walked[-1]["n_frames"] - 1  # the walk's last frame
    assert report["rested_from_frame"] > stood  # then it comes to rest and stands
    expected = rig.fk(np.asarray(rotations), np.asarray(translations))[: stood + 1]
    expected = expected[:, rig.at["pelvis"]]
    browser.execute_cdp_cmd(
        "Emulation.setDeviceMetricsOverride",
        {"width": 1280, "height": 760, "deviceScaleFactor": 1, "mobile": False},
    )
    try:
        open_page(browser, address)
        browser.execute_script("window.modbAvatar.stage.look([3.2, 5.0, -2.2], [-0.5, 0, 3.0])")
        browser.execute_script(
            "window.modbAvatar.send({type: 'mode', models: arguments[0], seed: arguments[1], "
            "goals: arguments[2]})",
            GRAPH,
            seed,
            goals,
        )
        wait_until(browser, lambda s: len(s["steps"]) >= 3, 30, "three steps")
        time.sleep(1.5)  # software WebGL needs real time to draw
        ARTIFACTS.mkdir(exist_ok=True)
        browser.save_screenshot(str(ARTIFACTS / "avatar-models.png"))
    finally:
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    state = wait_until(
        browser,
        lambda s: s["frame"] is not None and s["frame"]["index"] >= stood,
        60,
        "the last frame of the walk",
    )
    assert state["mode"] == {"models": GRAPH, "seed": seed}
    pelvis_at = browser.execute_script("return window.modbAvatar.state.pelvisAt")
    assert sorted(int(k) for k in pelvis_at)[: stood + 1] == list(range(stood + 1))
    shown = np.array([pelvis_at[str(k)] for k in range(stood + 1)])
    assert np.abs(shown - expected).max() < 1e-3
    played = [(s["node"], s["model"], s["first_frame"], s["n_frames"], s["candidates"])
              for s in state["steps"]]  # fmt: skip
    reported = [(s["node"], s["model"], s["first_frame"], s["n_frames"], s["candidates"])
                for s in walked]  # fmt: skip
    assert played == reported
    for s, r in zip(state["steps"], walked, strict=True):
        assert s["error_m"] == pytest.approx(r["error_m"], abs=1e-6)
        assert s["random_error_m"] == pytest.approx(r["random_error_m"], abs=1e-6)
    assert severe_console_entries(browser) == []


REACTION_SECONDS = 0.5  # a new goal answered: the heading turned 5 degrees toward it within this
LATEST_SECONDS = 0.75  # ... at every click: one landing in a step's last 0.37 s waits for the next


def reaction(rig: Rig, poses: list, click: dict) -> float:
    """turn_reaction on the poses the page kept (arrival times, the joints as it posed them)."""
    t = np.array([p["t"] for p in poses]) / 1000.0
    positions = np.array([p["positions"] for p in poses])
    heading = hips_heading(positions, rig.at["left_hip"], rig.at["right_hip"])
    pelvis = positions[:, rig.at["pelvis"]][:, [0, 2]]
    return turn_reaction(t, heading, pelvis, click["t"] / 1000.0, (click["x"], click["z"]))


def walking(rig: Rig, driver) -> tuple[np.ndarray, float]:
    """Where the pelvis is on the ground and the way the hips face, over the last second."""
    poses = driver.execute_script("return window.modbAvatar.state.poses")
    recent = [p for p in poses if p["t"] >= poses[-1]["t"] - 1000.0]
    facing = mean_heading([rig.heading(p["positions"]) for p in recent])
    return np.asarray(recent[-1]["positions"][rig.at["pelvis"]])[[0, 2]], facing


def steady(rig: Rig, driver, timeout: float = 6.0) -> None:
    """Until the avatar walks straight (walks_straight)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        poses = driver.execute_script("return window.modbAvatar.state.poses")
        t = np.array([p["t"] for p in poses]) / 1000.0
        if walks_straight(t, np.array([rig.heading(p["positions"]) for p in poses])):
            return
        time.sleep(0.1)
    raise AssertionError(f"the avatar did not walk straight within {timeout} s")


@pytest.mark.parametrize("mode", [GRAPH, ""], ids=["models", "motion matching"])
def test_a_new_goal_is_answered_within_half_a_second(server, browser, mode):
    """Clicked while the avatar walks straight, at three moments of a step, its heading turns 5
    degrees toward the new goal within REACTION_SECONDS of the click (the median; each within
    LATEST_SECONDS, where the click lands in a step's last moments and the next step turns). On
    models the step playing is planned again and blended into; in motion matching the snippet
    playing is chosen again toward the goal (or the next one is) and steered (synthesis.steer)."""
    address, dsn = server
    rig = Rig(dsn)
    open_page(browser, address)
    if mode:
        choose_mode(browser, mode)
    browser.execute_script("window.modbAvatar.stage.look([0, 9, -3], [0, 0, 3])")
    click_ground(browser, 0.0, 4.0)
    frames = wait_until(browser, lambda s: len(s["trail"]) > 0, 20, "the walk")["frames"]
    fps = 120.0  # CMU 16
    times, answered = [], []
    for k, pause in enumerate((1.0, 1.27, 1.13)):  # other phases of a step at each click
        # on a straight walk (a goal far ahead, sent as a click sends it) ...
        pelvis, facing = walking(rig, browser)
        far = ahead_and_aside(pelvis, facing, 8.0, 0.0)
        browser.execute_script(
            "window.modbAvatar.send({type: 'goal', x: arguments[0], z: arguments[1]})", *far
        )
        wait_until(browser, lambda s, f=frames: s["frames"] >= f + (0.5 + pause) * fps, 10, "on")
        steady(rig, browser)
        # ... a click 3 m to one side
        pelvis, facing = walking(rig, browser)
        x, z = ahead_and_aside(pelvis, facing, 1.0, 3.0 if k % 2 == 0 else -3.0)
        browser.execute_script(
            "window.modbAvatar.stage.look(arguments[0], arguments[1])",
            [x, 10.0, z - 3.0],
            [(x + pelvis[0]) / 2, 0.0, (z + pelvis[1]) / 2],
        )
        click_ground(browser, x, z)
        time.sleep(1.5)
        poses, clicks = browser.execute_script(
            "const s = window.modbAvatar.state; return [s.poses, s.clicks]"
        )
        times.append(reaction(rig, poses, clicks[-1]))
        state = page_state(browser)
        chosen = [m["receivedAt"] for m in state["messages"] if m["type"] == "choice"
                  and m["receivedAt"] >= clicks[-1]["t"]
                  and np.allclose(m["target"], (clicks[-1]["x"], clicks[-1]["z"]))]
        answered.append((chosen[0] - clicks[-1]["t"]) / 1000.0 if chosen else np.inf)
        frames = state["frames"]
    print(f"{mode or 'motion matching'}: heading turned after {np.round(times, 3)} s, "
          f"{'' if mode else f'the new snippet came after {np.round(answered, 3)} s'}")
    assert np.median(times) <= REACTION_SECONDS and max(times) <= LATEST_SECONDS, times
    assert severe_console_entries(browser) == []


def test_the_demos_graph_of_models_comes_first_and_its_link_starts_on_it(server, browser):
    """`modb demo`'s graph of models (MODEL_GRAPH) is the first graph the selector offers, named as
    the demo's, before one named ahead of it; /avatar?models=NAME (the link the demo prints) opens
    walking on it."""
    from modb.demo import MODEL_GRAPH
    from modb.models import graphs

    address, dsn = server
    other = "a-walk"  # before the demo's by name
    with psycopg.connect(dsn) as conn:  # GRAPH again under the demo's name, and another
        walk = graphs.load(conn, GRAPH)
        for name in (MODEL_GRAPH, other):
            graphs.save(conn, name, walk.skeleton_id, walk.data)
    try:
        browser.get(f"http://{address}/avatar?models={MODEL_GRAPH}")
        ready = browser.execute_async_script(
            "const done = arguments[0]; window.modbAvatar.ready.then(done, (e) => done(String(e)))"
        )
        assert ready is True, ready
        wait_until(browser, lambda s: s["mode"]["models"] == MODEL_GRAPH, 30, "the demo's graph")
        options = browser.execute_script(
            "return [...document.querySelectorAll('#mode option')].map((o) => o.textContent)"
        )
        assert options == ["motion matching: snippets",
                           f"graph of models: {MODEL_GRAPH} (modb demo's)",
                           f"graph of models: {other}", f"graph of models: {GRAPH}"]  # fmt: skip
        assert severe_console_entries(browser) == []
    finally:
        with psycopg.connect(dsn) as conn:
            for name in (MODEL_GRAPH, other):
                graphs.delete(conn, name)
