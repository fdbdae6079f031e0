"""Avatar mode in a real browser (Debian's chromium), against the real `modb serve` and database
with every locomotion clip of ../shared/mocap/bandai-2-dev and its transition graph: clicks set
goals the avatar walks to, the panel tunes this connection's selections, and the WebSocket keeps
other origins out."""

from __future__ import annotations

import contextlib
import json
import time

import numpy as np
import psycopg
import pytest
from support.browser import chromium, module_page, serving, severe_console_entries
from support.data import REPO
from support.databases import COLLECTION
from support.snippet_oracle import resolve_profile

from modb_kernel.joints import STANDARD_JOINTS

from modb.provenance import UNKNOWN_LICENCE

ARRIVAL_RADIUS = 0.5  # the page's default, metres
ARTIFACTS = REPO / "tests" / "artifacts"


@pytest.fixture(scope="module")
def avatar_server(locomotion):
    with serving(locomotion) as address:
        yield address, locomotion


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver, "1400,1000") as driver:
        yield driver


def open_avatar(driver, address: str) -> None:
    """The page, connected; its view stays where the test puts it (a view that follows the avatar
    would move between reading where a point shows and the click)."""
    from selenium.webdriver.common.by import By

    driver.get(f"http://{address}/avatar")
    ready = driver.execute_async_script(
        "const done = arguments[0]; window.modbAvatar.ready.then(done, (e) => done(String(e)))"
    )
    assert ready is True, ready
    driver.find_element(By.ID, "follow").click()


def page_state(driver) -> dict:
    return driver.execute_script(
        "const s = window.modbAvatar.state; return {goals: s.goals, goalIndex: s.goalIndex, "
        "frames: s.frames, frame: s.frame, choices: s.choices, messages: s.messages, "
        "trail: window.modbAvatar.trail()}"
    )


def wait_until(driver, condition, timeout: float, what: str) -> dict:
    """Polls the page's state until condition(state) holds."""
    deadline = time.monotonic() + timeout
    while True:
        state = page_state(driver)
        if condition(state):
            return state
        if time.monotonic() > deadline:
            raise AssertionError(
                f"{what}: not within {timeout} s; the page has {len(state['choices'])} selections, "
                f"goals {state['goals']}, last messages {state['messages'][-3:]}"
            )
        time.sleep(0.2)


def click_ground(driver, x: float, z: float, waypoint: bool = False) -> None:
    """A real pointer click (WebDriver actions) where the ground point (x, z) shows on the
    canvas."""
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


def look_at(driver, x: float, z: float) -> None:
    """Turns the view (as a user dragging it would) to look down on the ground point (x, z)."""
    driver.execute_script(
        "window.modbAvatar.stage.look([arguments[0], 12, arguments[1] - 6], "
        "[arguments[0], 0, arguments[1]])",
        x,
        z,
    )


def closest_approach(trail: list, goal: tuple[float, float]) -> float:
    points = np.asarray(trail, dtype=float)
    return (
        float(np.hypot(points[:, 0] - goal[0], points[:, 1] - goal[1]).min())
        if len(points)
        else np.inf
    )


def test_a_click_sets_a_goal_the_avatar_reaches_and_one_behind_it_turns_it_around(
    avatar_server, browser
):
    from selenium.webdriver.common.by import By

    address = avatar_server[0]
    open_avatar(browser, address)
    first = (1.0, 4.0)
    click_ground(browser, *first)
    state = wait_until(browser, lambda s: len(s["goals"]) == 1, 10, "the clicked goal")
    # the pointer's ground point
    assert np.hypot(*np.subtract(state["goals"][0], first)) < 0.1, state["goals"]
    first = tuple(state["goals"][0])
    look_at(browser, *first)
    state = wait_until(
        browser,
        lambda s: closest_approach(s["trail"], first) <= ARRIVAL_RADIUS,
        60,
        "the pelvis within the arrival radius of the first goal",
    )
    # Streamed at the capture's rate (30 fps here), by this test's clock: never ahead; behind only
    # by the queries that playback waits for (lead time 0) and a loaded machine.
    # (Each count is taken somewhere inside its script call: the bounds use the call's start or end,
    # whichever is safe, so a slow call on a loaded machine is not mistaken for running ahead.)
    asked0 = time.monotonic()
    before = page_state(browser)["frames"]
    answered0 = time.monotonic()
    time.sleep(3)
    asked1 = time.monotonic()
    after = page_state(browser)["frames"]
    answered1 = time.monotonic()
    fps = page_state(browser)["choices"][-1]["fps"]
    shortest, longest = asked1 - answered0, answered1 - asked0
    assert 0.5 * fps * shortest <= after - before <= fps * longest + 2, (after - before, longest)
    state = page_state(browser)
    # Behind: from where the pelvis is, against the direction of its last half metre of travel.
    trail = np.asarray(state["trail"])
    here = trail[-1]
    back = next(p for p in trail[::-1] if np.hypot(*(here - p)) >= 0.5)
    direction = (here - back) / np.hypot(*(here - back))
    behind = tuple(here - 4.0 * direction)
    look_at(browser, *(here + np.array(behind)) / 2)
    click_ground(browser, *behind)
    state = wait_until(
        browser,
        lambda s: len(s["goals"]) == 1 and np.hypot(*np.subtract(s["goals"][0], behind)) < 0.1,
        10,
        "the second goal",
    )
    second = tuple(state["goals"][0])
    start = len(state["trail"])
    state = wait_until(
        browser,
        lambda s: closest_approach(s["trail"][start:], second) <= ARRIVAL_RADIUS,
        90,
        "the pelvis within the arrival radius of the goal behind it",
    )
    walked = np.asarray(state["trail"][start:])
    # it turned: it went back the way it had come
    assert np.dot(walked[-1] - walked[0], direction) < -2.0
    # The streamed frames put the pelvis, as the page's own kinematics computes it, where each
    # selection said its snippet would end (the server's placement arithmetic).
    pelvis_at = browser.execute_script("return window.modbAvatar.state.pelvisAt")
    # (a snippet chosen again toward a new goal while it played replaced the step's first choice,
    # whose end was never played: the step's last choice counts)
    last = {m["step"]: m for m in state["messages"] if m["type"] == "choice"}
    ends = [(m["end_frame"], m["end"]["position"]) for m in last.values()]
    checked = [(str(f), p) for f, p in ends if str(f) in pelvis_at]
    assert len(checked) >= 10
    for frame, end in checked:
        assert np.hypot(pelvis_at[frame][0] - end[0], pelvis_at[frame][2] - end[2]) < 0.01, frame
    ARTIFACTS.mkdir(exist_ok=True)
    middle = (np.asarray(first) + np.asarray(second)) / 2
    browser.execute_script(
        "window.modbAvatar.stage.look([arguments[0] + 2, 6, arguments[1] - 6], "
        "[arguments[0], 0, arguments[1]])",
        *middle,
    )
    browser.find_element(By.ID, "follow").click()  # as the page starts: the view follows the avatar
    time.sleep(0.5)
    # the README's picture (docs/avatar-mode.png)
    browser.save_screenshot(str(ARTIFACTS / "avatar-mode.png"))
    assert severe_console_entries(browser) == []


# --- candidate counts, against a brute-force count over the stored features -----------------------


@pytest.fixture(scope="module")
def features(locomotion) -> dict:
    """Every snippet's begin and end feature point (as stored), pose key and rate; the profiles; the
    names."""
    with psycopg.connect(locomotion) as conn:
        rows = conn.execute(
            "SELECT s.id, s.pose_key, s.fps, b.features::text, e.features::text "
            "FROM modb.snippets s JOIN modb.terminators b ON b.id = s.begin_terminator "
            "JOIN modb.terminators e ON e.id = s.end_terminator ORDER BY s.id"
        ).fetchall()
        names = conn.execute("SELECT modb.feature_names()").fetchone()[0]
        profiles = dict(conn.execute("SELECT name, settings FROM modb.match_profiles").fetchall())
    point = lambda text: [float(v) for v in text.strip("()").split(",")]  # noqa: E731
    return {
        "index": {r[0]: k for k, r in enumerate(rows)},
        "pose": np.array([r[1] for r in rows]),
        "fps": np.array([r[2] for r in rows]),
        "begin": np.array([point(r[3]) for r in rows]),
        "end": np.array([point(r[4]) for r in rows]),
        "names": names,
        "profiles": profiles,
    }


def half_widths(features: dict, knobs: dict[str, str]) -> np.ndarray:
    """The box of the default profile with these knobs: a position feature of an included joint gets
    that joint's position threshold, a velocity one its velocity threshold (with velocity terms on),
    a rotation-matrix entry the chord of its angle threshold; the rest are unbounded."""
    plan = resolve_profile(features["profiles"]["default"], knobs)
    included = [STANDARD_JOINTS[j] for j in plan["joints"]]
    out = []
    for name in features["names"]:
        joint, axis = name.split(".")
        if joint not in included or (axis.startswith("v") and not plan["velocity_terms"]):
            out.append(1e6)
        elif axis.startswith("R"):
            out.append(2 * np.sin(min(plan["angle_threshold"][included.index(joint)], np.pi) / 2))
        else:
            key = "velocity_threshold" if axis.startswith("v") else "position_threshold"
            out.append(plan[key][included.index(joint)])
    return np.array(out)


def brute_force_count(features: dict, prev: int, level: int, knobs: dict[str, str]) -> int:
    """What select_next_snippet scores without a graph's stored transitions: the snippets of prev's
    pose and rate in the box of each level up to `level` (all of them at level 4), summed."""
    p = features["index"][prev]
    same = (features["pose"] == features["pose"][p]) & (features["fps"] == features["fps"][p])
    hw, f, c = half_widths(features, knobs), features["end"][p], features["begin"]
    total = 0
    for lvl in range(level + 1):
        if lvl == 4:
            total += int(same.sum())
        else:
            scale = 2.0**lvl
            inside = ((c >= f - scale * hw - 1e-4) & (c <= f + scale * hw + 1e-4)).all(axis=1)
            total += int((inside & same).sum())
    return total


def settings_changed(driver, since: int) -> dict:
    return wait_until(
        driver,
        lambda s: any(m["type"] in ("settings", "refused") for m in s["messages"][since:]),
        10,
        "the server's answer to the settings",
    )


def set_in_panel(driver, element_id: str, value: str) -> None:
    """What a user does: pick a value, or type one and leave the field (the change event)."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select

    element = driver.find_element(By.ID, element_id)
    if element.tag_name == "select":
        Select(element).select_by_value(value)
    else:  # select what is there and type over it: one change event, on leaving the field
        element.send_keys(Keys.CONTROL, "a")
        element.send_keys(value, Keys.TAB)


START_ATTEMPTS = 3  # clicks to start a walk whose first selection ran past the statement timeout


def walk_without_graph(driver, address: str, goal: tuple[float, float]) -> None:
    """A fresh page walking toward a far goal, choosing by the GiST box (no transition graph), once
    its first snippet is chosen. That first selection, from standing, ranks every snippet (57,616:
    over a CPU-second, where a step takes tens of milliseconds) against the avatar's 10 s statement
    timeout: on a busy machine it can run past it, and the page says "click to start again", as a
    user would (a few times at most; any other stop fails). A test that walks two pages starts one
    after the other, never two such queries at once."""
    open_avatar(driver, address)
    since = len(page_state(driver)["messages"])
    set_in_panel(driver, "graph", "none")  # the page starts with the newest current graph
    state = settings_changed(driver, since)
    assert (
        state["messages"][-1]["type"] == "settings"
        and state["messages"][-1]["settings"]["graph"] == "none"
    )
    for _ in range(START_ATTEMPTS):
        since = len(page_state(driver)["messages"])
        click_ground(driver, *goal)
        state = wait_until(
            driver,
            lambda s: any(m["type"] in ("choice", "stopped") for m in s["messages"][since:]),
            30,
            "the walk's first selection",
        )
        first = next(m for m in state["messages"][since:] if m["type"] in ("choice", "stopped"))
        if first["type"] == "choice":
            return
        assert "statement timeout" in first["message"], first
        time.sleep(1.0)  # the stopped walk's thread closes its connection before a click restarts
    raise AssertionError(f"no walk started in {START_ATTEMPTS} clicks: {first['message']}")


def counted(state: dict, after_message: int = 0) -> list[tuple[int, int, int]]:
    """(previous snippet, relax level, candidates reported) of the selections reported after a
    message."""
    out, previous = [], None
    for k, m in enumerate(state["messages"]):
        if m["type"] == "choice":
            if previous is not None and k >= after_message:
                out.append((previous, m["relax_level"], m["candidates"]))
            previous = m["snippet_id"]
    return out


def test_a_threshold_changed_in_the_panel_changes_the_candidate_counts_of_the_next_queries(
    avatar_server, browser, features
):
    address = avatar_server[0]
    walk_without_graph(browser, address, (0.0, 5.0))
    state = wait_until(browser, lambda s: len(counted(s)) >= 4, 30, "four selections")
    for prev, level, reported in counted(state):
        assert reported == brute_force_count(features, prev, level, {}), (prev, level)
    since = len(state["messages"])
    set_in_panel(browser, "position_threshold", "0.05")
    state = settings_changed(browser, since)
    answer = next(m for m in state["messages"][since:] if m["type"] in ("settings", "refused"))
    assert answer["type"] == "settings" and answer["settings"]["knobs"] == {
        "position_threshold": "0.05"
    }, answer
    changed_at = state["messages"].index(answer)
    # The selection in flight when the change arrived may still use the old thresholds: the ones
    # after it.
    state = wait_until(
        browser, lambda s: len(counted(s, changed_at)) >= 5, 30, "five selections after the change"
    )
    after = counted(state, changed_at)[1:]
    new = {"position_threshold": "0.05"}
    for prev, level, reported in after:
        assert reported == brute_force_count(features, prev, level, new), (prev, level)
    assert any(
        reported != brute_force_count(features, prev, level, {}) for prev, level, reported in after
    )
    assert_readouts_summarise_the_last_selections(browser)
    assert severe_console_entries(browser) == []


def assert_readouts_summarise_the_last_selections(driver) -> None:
    """The panel shows figures over the last 50 selections: recomputed here from the selections
    reported, and read from the page in the same step as the cells it shows."""
    messages, cells = driver.execute_script(
        "return [window.modbAvatar.state.messages, Object.fromEntries(['latency', 'selections', "
        "'candidates', "
        "'relax', 'seams', 'node', 'source']"
        ".map((id) => [id, document.getElementById(id).textContent]))]"
    )
    choices = [m for m in messages if m["type"] == "choice"]
    last, window = choices[-1], choices[-50:]
    latencies = [c["latency_ms"] for c in window]
    seams = np.array([c["continuity"] for c in window if c["continuity"] is not None])
    relaxed = np.mean([c["relax_level"] > 0 for c in window])
    r = last["readout"]
    assert r["selections"] == len(window)
    assert r["latency_p50_ms"] == pytest.approx(np.median(latencies))
    assert r["latency_p99_ms"] == pytest.approx(np.percentile(latencies, 99))
    assert r["seam_ratio_median"] == pytest.approx(np.median(seams))
    assert r["seam_ratio_max"] == pytest.approx(seams.max())
    assert (
        r["seam_rough_share"] == pytest.approx(np.mean(seams > 1))
        and r["candidates"] == last["candidates"]
    )
    assert r["relaxed_share"] == pytest.approx(relaxed)
    assert cells == {
        "latency": f"{np.median(latencies):.1f} / {np.percentile(latencies, 99):.1f} ms",
        "selections": str(len(window)),
        "candidates": str(last["candidates"]),
        "relax": f"{last['relax_level']} (relaxed {100 * relaxed:.0f}%)",
        "seams": f"r median {np.median(seams):.2f}, max {seams.max():.2f}; "
        f"{100 * np.mean(seams > 1):.0f}% over 1",
        "node": last["node"],  # the server has no standbys: every session on its primary
        "source": last["source"]["collection"],  # where the snippet's motion was loaded
    }
    assert last["node"] == "primary"
    assert all(c["source"] and c["source"]["collection"] for c in choices)


def test_two_browser_connections_with_different_settings_do_not_affect_each_other(
    avatar_server, browser, features
):
    from selenium.webdriver.common.by import By

    address = avatar_server[0]
    with chromium("1400,1000") as other:
        walk_without_graph(browser, address, (0.0, 5.0))
        walk_without_graph(other, address, (-1.0, 5.0))
        since = len(page_state(browser)["messages"])
        set_in_panel(browser, "position_threshold", "0.08")
        set_in_panel(browser, "velocity_terms", "off")  # the box no longer bounds velocities
        state = wait_until(
            browser,
            lambda s: sum(m["type"] == "settings" for m in s["messages"][since:]) >= 2,
            10,
            "both settings answered",
        )
        mine = {"position_threshold": "0.08", "velocity_terms": "off"}
        assert [m for m in state["messages"] if m["type"] == "settings"][-1]["settings"][
            "knobs"
        ] == mine
        changed_at = len(state["messages"])
        # The other page leaves the wrists out of the comparison (their features are then
        # unbounded).
        other_since = len(page_state(other)["messages"])
        for wrist in ("left_wrist", "right_wrist"):
            other.find_element(By.CSS_SELECTOR, f"input[name=joint][value={wrist}]").click()
        theirs_state = wait_until(
            other,
            lambda s: sum(m["type"] == "settings" for m in s["messages"][other_since:]) >= 2,
            10,
            "the other page's settings answered",
        )
        without_wrists = [j for j in STANDARD_JOINTS if j not in ("left_wrist", "right_wrist")]
        theirs_knobs = {"joints": ",".join(without_wrists)}
        assert [m for m in theirs_state["messages"] if m["type"] == "settings"][-1]["settings"][
            "knobs"
        ] == theirs_knobs
        other_changed_at = len(theirs_state["messages"])
        wait_until(
            browser, lambda s: len(counted(s, changed_at)) >= 4, 30, "selections after the change"
        )
        theirs = wait_until(
            other,
            lambda s: len(counted(s, other_changed_at)) >= 4,
            30,
            "the other page's selections",
        )
        ours = page_state(browser)
        # Each page's selections count by its own settings, never the other's.
        assert [m["settings"]["knobs"] for m in ours["messages"] if m["type"] == "settings"][
            -1
        ] == mine
        for prev, level, reported in counted(theirs, other_changed_at)[1:]:
            assert reported == brute_force_count(features, prev, level, theirs_knobs), (prev, level)
        assert any(
            reported != brute_force_count(features, prev, level, mine)
            for prev, level, reported in counted(theirs, other_changed_at)[1:]
        )
        for prev, level, reported in counted(ours, changed_at)[1:]:
            assert reported == brute_force_count(features, prev, level, mine), (prev, level)
        assert any(
            reported != brute_force_count(features, prev, level, {})
            for prev, level, reported in counted(ours, changed_at)[1:]
        )
        assert severe_console_entries(other) == []


def test_shift_click_adds_waypoints_served_in_order_and_the_goals_are_marked(
    avatar_server, browser
):
    open_avatar(browser, avatar_server[0])
    look_at(browser, 1.0, 4.0)
    click_ground(browser, 0.0, 3.0)
    click_ground(browser, 2.5, 5.5, waypoint=True)
    state = wait_until(browser, lambda s: len(s["goals"]) == 2, 10, "the goal and its waypoint")
    goals = [tuple(g) for g in state["goals"]]
    assert (
        np.hypot(*np.subtract(goals[0], (0.0, 3.0))) < 0.1
        and np.hypot(*np.subtract(goals[1], (2.5, 5.5))) < 0.1
    )
    marks = browser.execute_script(
        "const c = window.modbAvatar.course; return [c.current.visible, "
        "c.current.position.toArray(), c.waypoints.map((w) => w.position.toArray())]"
    )
    assert marks[0] and np.hypot(marks[1][0] - goals[0][0], marks[1][2] - goals[0][1]) < 1e-6
    assert (
        len(marks[2]) == 1
        and np.hypot(marks[2][0][0] - goals[1][0], marks[2][0][2] - goals[1][1]) < 1e-6
    )
    state = wait_until(
        browser,
        lambda s: closest_approach(s["trail"], goals[1]) <= ARRIVAL_RADIUS,
        90,
        "the pelvis within the arrival radius of the waypoint",
    )
    trail = np.asarray(state["trail"])
    near = [np.flatnonzero(np.hypot(*(trail - g).T) <= ARRIVAL_RADIUS) for g in goals]
    assert len(near[0]) and near[0][0] < near[1][0]  # the goal first, then the waypoint
    # The marker moved on to the waypoint once the goal was served.
    wait_until(
        browser, lambda s: s["goalIndex"] == 1, 10, "the waypoint marked as the goal being served"
    )
    current = browser.execute_script("return window.modbAvatar.course.current.position.toArray()")
    assert np.hypot(current[0] - goals[1][0], current[2] - goals[1][1]) < 1e-6


def test_every_panel_control_reaches_this_connections_settings(avatar_server, browser, features):
    from selenium.webdriver.common.by import By

    open_avatar(browser, avatar_server[0])

    def answer(element_id: str | None, value: str | None, click: str | None = None) -> dict:
        since = len(page_state(browser)["messages"])
        if click:
            browser.find_element(By.CSS_SELECTOR, click).click()
        else:
            set_in_panel(browser, element_id, value)
        return next(
            m
            for m in settings_changed(browser, since)["messages"][since:]
            if m["type"] in ("settings", "refused")
        )

    locomotion_joints = features["profiles"]["locomotion"]["joints"]
    settings = answer("profile", "locomotion")["settings"]
    # its own joints: no knob
    assert settings["profile"] == "locomotion" and settings["knobs"] == {}
    shown = [
        e.get_attribute("value")
        for e in browser.find_elements(By.CSS_SELECTOR, "input[name=joint]:checked")
    ]
    assert sorted(shown) == sorted(locomotion_joints)
    settings = answer(None, None, click="input[name=joint][value=pelvis]")["settings"]
    assert settings["knobs"] == {
        "joints": ",".join(j for j in STANDARD_JOINTS if j in locomotion_joints and j != "pelvis")
    }
    assert answer("norm", "l1")["settings"]["knobs"]["norm"] == "l1"
    assert answer("velocity_terms", "off")["settings"]["knobs"]["velocity_terms"] == "off"
    assert (
        answer("angular_velocity_threshold", "3.5")["settings"]["knobs"][
            "angular_velocity_threshold"
        ]
        == "3.5"
    )
    assert answer("lead_time", "0.3")["settings"]["lead_time"] == 0.3
    assert answer("arrival_radius", "1")["settings"]["arrival_radius"] == 1.0
    assert answer("collection", COLLECTION)["settings"]["collection"] == COLLECTION
    assert answer("graph", "none")["settings"]["graph"] == "none"
    assert answer("graph", "")["settings"]["graph"] is None  # automatic: the newest current graph
    refused = answer("position_threshold", "-1")
    assert refused["type"] == "refused" and "Thresholds must be positive" in refused["message"]
    assert browser.find_element(By.ID, "status").text == refused["message"]
    # back to what is in force
    assert browser.find_element(By.ID, "position_threshold").get_attribute("value") == ""
    assert refused["settings"]["knobs"] == {
        "joints": settings["knobs"]["joints"],
        "norm": "l1",
        "velocity_terms": "off",
        "angular_velocity_threshold": "3.5",
    }


# --- the WebSocket itself -------------------------------------------------------------------------


@contextlib.contextmanager
def socket_to(address: str, origin: str | None):
    from websockets.sync.client import connect

    with connect(f"ws://{address}/ws/avatar", origin=origin, open_timeout=10) as ws:
        yield ws


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://127.0.0.1:1"])
def test_the_websocket_refuses_a_foreign_origin(avatar_server, origin):
    from websockets.exceptions import InvalidStatus

    address = avatar_server[0]
    with pytest.raises(InvalidStatus) as refused, socket_to(address, origin):
        pass
    assert refused.value.response.status_code == 403
    with socket_to(address, f"http://{address}") as ws:  # its own page may
        assert json.loads(ws.recv(10))["type"] == "ready"


def test_bad_settings_are_refused_with_the_reason_and_the_walk_goes_on(avatar_server):
    with socket_to(avatar_server[0], None) as ws:
        assert json.loads(ws.recv(10))["type"] == "ready"
        for message, reason in [
            ({"knobs": {"position_threshold": "-1"}}, "Thresholds must be positive"),
            ({"knobs": {"joints": "pelvis,tail"}}, '"tail" is not a standard joint'),
            ({"knobs": {"graph_lookahead": "on"}}, "unknown knob 'graph_lookahead'"),
            ({"profile": "nope"}, 'unknown match profile "nope"'),
            ({"graph": "nope"}, 'no transition graph "nope"'),
            ({"lead_time": 5}, "lead_time must be"),
        ]:
            ws.send(json.dumps({"type": "settings", **message}))
            answer = json.loads(ws.recv(10))
            assert answer["type"] == "refused" and reason in answer["message"], (message, answer)
            assert answer["settings"]["knobs"] == {} and answer["settings"]["profile"] == "default"
        ws.send(json.dumps({"type": "goal", "x": 0, "z": 3}))
        kinds = set()
        deadline = time.monotonic() + 20
        while "frame" not in kinds and time.monotonic() < deadline:
            kinds.add(json.loads(ws.recv(10))["type"])
        assert {"goals", "skeleton", "choice", "frame"} <= kinds


def test_the_avatar_is_a_skinned_character_and_its_walk_downloads_as_bvh_and_gltf(
    avatar_server, browser, tmp_path
):
    import base64

    import pygltflib
    from selenium.webdriver.common.by import By
    from support.commands import run_modb
    from support.gltf_validator import validate

    address, dsn = avatar_server
    open_avatar(browser, address)
    look_at(browser, 0.0, 3.0)
    click_ground(browser, 0.0, 3.0)
    wait_until(browser, lambda s: len(s["choices"]) >= 3, 30, "three selections")
    character = browser.execute_script(
        "const s = window.modbAvatar; const c = s.state.character; if (!c) return null; "
        "let skinned = 0; s.stage.scene.traverse((o) => { if (o.isSkinnedMesh) skinned += 1; }); "
        "return {skinned, bones: c.bones.length, skeletonShown: s.stage.bones.visible}"
    )
    assert character == {"skinned": 1, "bones": 22, "skeletonShown": False}
    browser.find_element(By.ID, "show-skeleton").click()
    assert browser.execute_script("return window.modbAvatar.stage.bones.visible") is True
    for fmt in ("bvh", "glb"):
        browser.find_element(By.ID, f"download-{fmt}").click()
        state = wait_until(
            browser,
            lambda s, fmt=fmt: any(
                m["type"] == "file" and m["name"] == f"walk.{fmt}" for m in s["messages"]
            ),
            30,
            f"the walk as {fmt}",
        )
        message = next(
            m
            for m in reversed(state["messages"])
            if m["type"] == "file" and m["name"].endswith(fmt)
        )
        path = tmp_path / f"avatar-{message['name']}"  # its own clip name when loaded back
        path.write_bytes(base64.b64decode(message["data"]))
        assert message["seconds"] > 1.0
        if fmt == "glb":
            assert validate(path)["numErrors"] == 0
            # the sources played, with their terms, inside the file and on the page
            asset = pygltflib.GLTF2().load_binary(str(path)).asset
            played = {
                (c["source"]["collection"], c["source"]["licence"] or UNKNOWN_LICENCE)
                for c in state["choices"]
            }
            named = {(x["source"], x["licence"]) for x in asset.extras["sources"]}
            assert named and named <= played
            assert asset.copyright == message["sources"]
        else:  # the loader reads it back: one clip of the walk's length
            r = run_modb(dsn, "load", path, "--collection", "downloaded", "--no-snippets")
            assert r.returncode == 0, r.stderr
    assert severe_console_entries(browser) == []


def test_at_the_goal_the_avatar_comes_to_rest_where_the_data_can_or_says_it_cannot(
    avatar_server, cmu, browser
):
    """CMU 131 has stopping and standing motion: the page's avatar stands at the goal. Bandai's
    locomotion takes have none: the page says so and the avatar walks on."""
    for dsn, address in ((cmu, None), (avatar_server[1], avatar_server[0])):
        with contextlib.ExitStack() as stack:
            if address is None:
                address = stack.enter_context(serving(dsn))
            open_avatar(browser, address)
            look_at(browser, 0.0, 2.0)
            click_ground(browser, 0.0, 2.0)
            state = wait_until(
                browser, lambda s: any(c["reached"] for c in s["choices"]), 40, "the goal reached"
            )
            reached_at = next(c["end_frame"] for c in state["choices"] if c["reached"])
            fps = state["choices"][-1]["fps"]
            state = wait_until(
                browser, lambda s: s["frame"]["index"] > reached_at + 4 * fps, 30, "4 s more"
            )
            pelvis = browser.execute_script("return window.modbAvatar.state.pelvisAt")
            frames = sorted(int(k) for k in pelvis if int(k) >= reached_at + 2 * fps)
            path = np.array([pelvis[str(k)] for k in frames])
            speed = np.linalg.norm(np.diff(path[:, [0, 2]], axis=0), axis=1) * fps
            quarter = max(1, int(fps / 4))
            smooth = np.convolve(speed, np.ones(quarter) / quarter, mode="valid")
            notes = [m["message"] for m in state["messages"] if m["type"] == "note"]
            if dsn == cmu:
                assert smooth.max() < 0.1, smooth.max()
                assert np.hypot(path[:, 0], path[:, 2] - 2.0).max() < 0.75
            else:
                assert any("has no motion that stops or stands" in n for n in notes), notes
                assert smooth.min() > 0.1
    assert severe_console_entries(browser) == []
