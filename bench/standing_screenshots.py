"""Screenshots of the avatar page in models mode after the character has arrived and stands,
idling (issue 60): the real `modb serve` and Debian's headless chromium, as the tests drive them.

    .venv/bin/python bench/standing_screenshots.py DSN GRAPH X,Z OUT.png

The goal X,Z is sent with the mode (as a click would), the page is watched until the goal is
served and the character has come to rest, and then for a few seconds more: the picture is taken
while it idles. Prints how far the pelvis moved while idling and how many frames came.
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import chromium, serving  # noqa: E402

IDLE_SECONDS = 4.0


def main() -> None:
    dsn, graph, goal, out = sys.argv[1], sys.argv[2], sys.argv[3], Path(sys.argv[4])
    x, z = (float(v) for v in goal.split(","))
    with serving(dsn) as address, chromium("1280,760") as driver:
        driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
            "width": 1280, "height": 760, "deviceScaleFactor": 1, "mobile": False})
        driver.get(f"http://{address}/avatar")
        driver.execute_async_script(
            "const done = arguments[0]; window.modbAvatar.ready.then(done, (e) => done(String(e)))")
        driver.execute_script("window.modbAvatar.send({type: 'mode', models: arguments[0], "
                              "seed: 1, goals: [[arguments[1], arguments[2]]]})", graph, x, z)
        deadline = time.monotonic() + 60
        while driver.execute_script("return window.modbAvatar.state.goalIndex") < 1:
            if time.monotonic() > deadline:
                state = driver.execute_script("return window.modbAvatar.state.messages.slice(-3)")
                raise SystemExit(f"the goal was not served within 60 s: {state}")
            time.sleep(0.2)
        time.sleep(3.0)  # the last step and the settle
        driver.find_element("id", "follow").click()  # the view stays: near, in front of it
        rest = driver.execute_script("const s = window.modbAvatar.state; "
                                     "return s.pelvisAt[s.frame.index]")
        driver.execute_script("window.modbAvatar.stage.look(arguments[0], arguments[1])",
                              [rest[0] + 1.4, 1.5, rest[-1] + 2.6], [rest[0], 0.8, rest[-1]])
        before = driver.execute_script("const s = window.modbAvatar.state; "
                                       "return [s.frames, s.pelvisAt[s.frame.index]]")
        time.sleep(IDLE_SECONDS)
        after = driver.execute_script("const s = window.modbAvatar.state; "
                                      "return [s.frames, s.pelvisAt[s.frame.index]]")
        driver.save_screenshot(str(out))
    moved = float(np.linalg.norm((np.asarray(after[1]) - before[1])[[0, -1]]))  # (x, [y,] z)
    print(f"{out}: {after[0] - before[0]} frames in {IDLE_SECONDS:g} s of idling; the pelvis "
          f"moved {100 * moved:.1f} cm on the ground")


if __name__ == "__main__":
    main()
