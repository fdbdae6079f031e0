"""The web view's Models panel in headless Chromium (issue 44, item 4): the motion models listed per
collection; one chosen shows its summary and a bar per spatial PCA component (read back from the
canvas's pixels, against the shares the REST answer gives), and plays its samples in a row in front
of its training examples, each figure posed as the server's forward kinematics has it."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from selenium.webdriver.common.by import By
from support.browser import get, module_page, serving, severe_console_entries
from support.commands import run_modb
from support.data import REPO

ARTIFACTS = REPO / "tests" / "artifacts"
TOLERANCE_M = 0.01  # the page's pose against the server's, as test_web.py holds clips to
MODEL = "cmu16_left_step"


@pytest.fixture(scope="module")
def site(cmu16_walks):
    """CMU subject 16's walks with their steps found and a model of the left steps, served: a copy
    of conftest's cmu16_walks less its graph of models and its other models (the right steps', and
    the turning steps' the graph's family built)."""
    with cmu16_walks(f"models_web_{os.getpid()}") as dsn:
        for args in (("model", "graph", "delete", "walk"), ("model", "delete", "cmu16_right_step"),
                     ("model", "delete", "walk_left_turning_step"),
                     ("model", "delete", "walk_right_turning_step")):  # fmt: skip
            r = run_modb(dsn, *args, process=False)
            assert r.returncode == 0, (args, r.stderr)
        with serving(dsn) as address:
            yield address


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


def open_page(browser, address: str) -> None:
    browser.get(f"http://{address}/")
    assert (
        browser.execute_async_script(
            "const done = arguments[0]; "
            "Promise.all([window.modbViewer.ready, window.modbModels.ready])"
            ".then(() => done('ok'), (e) => done(String(e)))"
        )
        == "ok"
    )


def show(browser, n: int, seed: int) -> None:
    """Asks the panel for n samples drawn with seed, and waits until they play. (Typed in by script:
    with twenty skinned figures software WebGL takes the page's time, and each of WebDriver's
    element commands takes seconds.)"""
    browser.execute_script(
        "document.getElementById('model-n').value = arguments[0]; "
        "document.getElementById('model-seed').value = arguments[1]; "
        "document.getElementById('model-show').click()",
        str(n),
        str(seed),
    )
    wait_for(browser, f"return window.modbModels.shown.samples === {n}")


# What the page shows, read at one moment: the panel's texts, the plot's pixels, each figure's pose
# and whether all its joints are in the camera's view, and whether the clip's character is shown.
SNAPSHOT = """
const m = window.modbModels, s = window.modbViewer.stage;
const c = document.getElementById('model-variance'), g = c.getContext('2d');
const figures = m.figures();
return {
  shown: m.shown, variancePlotted: m.variancePlotted,
  summary: document.getElementById('model-summary').textContent,
  plot: [c.width, c.height, Array.from(g.getImageData(0, 0, c.width, c.height).data)],
  figures, inView: figures.map((f) => f.joints.every((p) => s.offsetOf(...p).visible)),
  clipShown: s.character !== null,
};
"""


def bar_heights(plot) -> tuple[list[int], int]:
    """The variance plot's bars as drawn: per run of bar-blue pixels along the bottom row, the
    number of bar-blue pixels in its middle column; and the plot's height in pixels."""
    w, h, rgba = plot
    px = np.array(rgba, dtype=int).reshape(h, w, 4)
    blue = (px[..., 3] > 128) & (px[..., 2] > px[..., 0] + 60)  # #2f6fc4; the line is orange
    edges = np.flatnonzero(np.diff(np.r_[0, blue[-1].astype(int), 0]))
    runs = list(zip(edges[::2], edges[1::2], strict=True))
    return [int(blue[:, (a + b - 1) // 2].sum()) for a, b in runs], h


def assert_posed_as_the_server_has_them(figures, answer, key):
    """Each figure's joints, less its place on the stage, are the answer's positions at the
    figure's frame."""
    motions = answer[key]
    assert sorted(f["index"] for f in figures) == list(range(len(motions)))
    for f in figures:
        expected = np.array(motions[f["index"]]["positions"][f["frame"]])
        shown = np.array(f["joints"]) - np.array(f["offset"])
        assert np.abs(shown - expected).max() < TOLERANCE_M, (key, f["index"], f["frame"])


def test_the_panel_lists_a_model_plots_its_variance_plays_samples_beside_examples(site, browser):
    address = site
    status, listed = get(address, "/api/motion-models")
    assert status == 200 and [m["name"] for m in listed] == [MODEL]
    status, model = get(address, f"/api/motion-models/{MODEL}")
    assert status == 200
    shares = model["spatial_explained"]
    open_page(browser, address)

    # The listing: the collection, under it the model with its version, primitive and examples.
    panel = browser.find_element(By.ID, "models-panel")
    assert panel.is_displayed()
    entry = browser.find_element(By.CSS_SELECTOR, f"#models span[data-model='{MODEL}']")
    assert browser.find_element(By.CSS_SELECTOR, "#models > li").text.startswith("cmu16")
    assert entry.text == f"{MODEL} v1 · left_step · {model['examples']} examples"

    # Chosen: its summary, a bar per spatial component, 10 samples and 10 examples playing.
    entry.click()
    wait_for(browser, "return window.modbModels.shown.samples === 10")
    page = browser.execute_script(SNAPSHOT)
    summary = page["summary"]
    assert f"{model['examples']} examples ({model['mirrored_examples']} mirrored)" in summary
    assert f"{len(shares)} spatial + {len(model['temporal_explained'])} temporal" in summary
    assert page["shown"] == {"samples": 10, "examples": 10}
    assert page["variancePlotted"] == len(shares)
    heights, h = bar_heights(page["plot"])
    assert len(heights) == len(shares)
    expected = np.maximum(1, np.round(h * np.array(shares) / max(shares)))
    assert np.abs(np.array(heights) - expected).max() <= 3, (heights, expected.tolist())

    # Every figure stands where the server's kinematics puts it, in two rows, all in view.
    samples = get(address, f"/api/motion-models/{MODEL}/samples?n=10&seed=0")[1]
    examples = get(address, f"/api/motion-models/{MODEL}/examples?n=10")[1]
    figures = page["figures"]
    by_kind = {k: [f for f in figures if f["kind"] == k] for k in ("samples", "examples")}
    assert_posed_as_the_server_has_them(by_kind["samples"], samples, "samples")
    assert_posed_as_the_server_has_them(by_kind["examples"], examples, "examples")
    rows = {k: {f["offset"][2] for f in fs} for k, fs in by_kind.items()}
    assert len(rows["samples"]) == len(rows["examples"]) == 1
    assert rows["samples"] != rows["examples"]
    for fs in by_kind.values():
        xs = sorted(f["offset"][0] for f in fs)
        assert min(np.diff(xs)) >= 0.7  # metres: neighbours do not overlap
    assert all(page["inView"]) and not page["clipShown"]
    # ... and they loop: the frames move on
    frames = [f["frame"] for f in figures]
    wait_for(browser, f"return window.modbModels.figures().some((f, i) => f.frame !== {frames}[i])")

    # Asked for 3 samples with another seed: the server's draw for that seed, not the last one's.
    show(browser, 3, 7)
    page = browser.execute_script(SNAPSHOT)
    assert page["shown"] == {"samples": 3, "examples": 3}
    other = get(address, f"/api/motion-models/{MODEL}/samples?n=3&seed=7")[1]
    assert other["samples"][0]["positions"] != samples["samples"][0]["positions"]
    drawn = [f for f in page["figures"] if f["kind"] == "samples"]
    assert_posed_as_the_server_has_them(drawn, other, "samples")

    # Back to the clip: the model's figures go, the clip's character comes back and plays.
    browser.find_element(By.ID, "model-close").click()
    assert browser.execute_script("return window.modbModels.shown") == {"samples": 0, "examples": 0}
    assert browser.execute_script(
        "const v = window.modbViewer; "
        "return v.stage.character === v.state.character && v.state.playing"
    )
    assert severe_console_entries(browser) == []


def test_the_picture_of_the_docs(site, browser):
    """docs/models-view.png (copied from tests/artifacts/models-view.png): drawn at full density,
    after the software WebGL has had time to draw."""
    browser.execute_cdp_cmd(
        "Emulation.setDeviceMetricsOverride",
        {"width": 1280, "height": 760, "deviceScaleFactor": 1, "mobile": False},
    )
    try:
        open_page(browser, site)
        browser.find_element(By.CSS_SELECTOR, f"#models span[data-model='{MODEL}']").click()
        wait_for(browser, "return window.modbModels.shown.samples === 10")
        browser.execute_script("document.getElementById('models-panel').scrollIntoView()")
        time.sleep(2.5)
        ARTIFACTS.mkdir(exist_ok=True)
        browser.save_screenshot(str(ARTIFACTS / "models-view.png"))
    finally:
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    assert severe_console_entries(browser) == []
