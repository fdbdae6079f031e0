"""The real `modb serve` and Debian's chromium (through chromium-driver), for the browser tests."""

from __future__ import annotations

import contextlib
import http.client
import json
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
MODB = (sys.executable, "-m", "modb.cli")  # the command line of the environment running the tests


def fetch(address: str, path: str, headers: dict[str, str] | None = None) -> tuple[int, str, bytes]:
    """GET: the status, the content type and the body as it came."""
    conn = http.client.HTTPConnection(address, timeout=30)
    try:
        conn.request("GET", path, headers=headers or {})
        response = conn.getresponse()
        return response.status, response.getheader("content-type", ""), response.read()
    finally:
        conn.close()


def get(address: str, path: str, headers: dict[str, str] | None = None) -> tuple[int, dict]:
    """GET of a JSON endpoint: the status and the decoded body."""
    status, _, body = fetch(address, path, headers)
    return status, json.loads(body or b"null")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def serving(dsn: str, *options: str, modb: tuple[str, ...] = MODB, cwd: Path | None = None):
    """The real `modb serve` (with `options`) on a free port; yields its host:port. `modb` is the
    command (this environment's by default), run in `cwd`."""
    port = _free_port()
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen(
        [*modb, "--dsn", dsn, "serve", "--port", str(port), *options],
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=cwd,
    )
    address = f"127.0.0.1:{port}"
    for _ in range(150):
        try:
            if get(address, "/api/collections")[0] in (200, 401):  # 401: --require-token
                break
        except OSError:
            if proc.poll() is not None:
                break
            time.sleep(0.2)
    else:
        proc.kill()
    if proc.poll() is not None:
        log.seek(0)
        pytest.fail(f"modb serve did not start:\n{log.read().decode()}")
    try:
        yield address
    finally:
        proc.terminate()
        proc.wait(10)


# requestAnimationFrame by a 500 ms timer, before a page's own scripts (module_page): the pages draw
# (software WebGL, in chromium's GPU process) on every animation frame, playing or not, as often as
# the CPU lets them, a core taken from the other worker (models_web's first test: 31 s of the GPU
# process's CPU at 100 ms, 7 s at 500 ms). Animation goes by the clock (the time since the last
# frame), avatar frames as they arrive, and what the tests read (a figure's joints, a point's place
# on the canvas) is computed when read, not when drawn: only how often the pages draw changes. A
# picture for the docs sleeps a second or more before it is taken.
FEW_FRAMES = """
window.requestAnimationFrame = (callback) => setTimeout(() => callback(performance.now()), 500);
window.cancelAnimationFrame = (id) => clearTimeout(id);
"""


@contextlib.contextmanager
def chromium(size: str = "1280,800"):
    """A headless chromium with a fresh profile (skips, saying why, where it is not installed)."""
    if not (CHROMIUM.exists() and CHROMEDRIVER.exists()):
        pytest.skip(
            "Debian's chromium and chromium-driver are not installed (`make setup` installs them)"
        )
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    profile = tempfile.mkdtemp(prefix="modb-chromium-")
    for flag in (
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--no-first-run",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--enable-unsafe-swiftshader",  # software WebGL: headless Chromium needs an opt-in for it
        f"--window-size={size}",
        # A low-density display: software WebGL draws a quarter of the pixels (the page and its
        # coordinates are the same in CSS pixels): chromium takes much less of the workers' CPU.
        "--force-device-scale-factor=0.5",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


@contextlib.contextmanager
def module_page(driver, size: str = "1280,800", few_frames: bool = True):
    """The worker's browser (conftest's chromium_driver) for one module: a blank page at `size`,
    the console log of earlier modules read away, no cookies (each `serving` has its own origin, so
    its storage starts empty). Its pages draw two frames a second (FEW_FRAMES) unless `few_frames`
    is false (a module that watches playback frame by frame). Blank again after the module: a page
    left open goes on drawing (software WebGL), a core's worth of CPU for the rest of the run."""
    driver.get("about:blank")
    driver.delete_all_cookies()
    width, height = (int(v) for v in size.split(","))
    driver.set_window_size(width, height)
    driver.get_log("browser")
    added = None
    if few_frames:
        added = driver.execute_cdp_cmd(
            "Page.addScriptToEvaluateOnNewDocument", {"source": FEW_FRAMES}
        )
    try:
        yield driver
    finally:
        driver.get("about:blank")
        if added is not None:
            driver.execute_cdp_cmd(
                "Page.removeScriptToEvaluateOnNewDocument", {"identifier": added["identifier"]}
            )


def severe_console_entries(driver) -> list[dict]:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
