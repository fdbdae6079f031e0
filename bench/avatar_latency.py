"""Every selection's latency on the avatar page (issue 61: at most 50 ms, the first and the last
included): the real `modb serve` and Debian's headless chromium, as the tests drive them.

    .venv/bin/python bench/avatar_latency.py DSN [X,Z ...]

The page is opened in a new browser profile (a new server process: its first selection is a new
session's); each goal is sent as a click would, once the avatar has reached the one before and,
where its data has motion that stops, come to rest there (the next walk then sets off from
standing). Prints what the server reported for each selection (`latency_ms`, measured around the
query) as p50, p99 and max, with the first and last.
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import chromium, serving  # noqa: E402

GOALS = [(1.0, 4.0), (-2.0, 1.0), (2.0, -2.0)]
TIMEOUT_SECONDS = 60
REACHED = (
    "return window.modbAvatar.state.messages.filter((m) => m.type === 'choice' && m.reached).length"
)
REST_SECONDS = 4.0


def main() -> None:
    dsn = sys.argv[1]
    goals = [tuple(float(v) for v in g.split(",")) for g in sys.argv[2:]] or GOALS
    with serving(dsn) as address, chromium("1000,700") as driver:
        driver.get(f"http://{address}/avatar")
        driver.execute_async_script(
            "const done = arguments[0]; window.modbAvatar.ready.then(done, (e) => done(String(e)))"
        )
        reached = 0
        for x, z in goals:
            driver.execute_script(
                "window.modbAvatar.send({type: 'goal', x: arguments[0], "
                "z: arguments[1], add: false})",
                x,
                z,
            )
            deadline = time.monotonic() + TIMEOUT_SECONDS
            while time.monotonic() < deadline:
                time.sleep(0.5)
                if driver.execute_script(REACHED) > reached:
                    reached += 1
                    time.sleep(REST_SECONDS)  # coming to rest there, where the data can
                    break
            else:
                print(f"the goal {x:g},{z:g} was not reached in {TIMEOUT_SECONDS} s")
        choices = driver.execute_script(
            "return window.modbAvatar.state.messages.filter((m) => m.type === 'choice')"
        )
    ms = np.array([c["latency_ms"] for c in choices if c.get("latency_ms") is not None])
    print(
        f"{len(ms)} selections through {len(goals)} goals ({reached} reached): "
        f"p50 {np.median(ms):.1f} ms, "
        f"p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms "
        f"(first {ms[0]:.1f} ms, last {ms[-1]:.1f} ms)"
    )


if __name__ == "__main__":
    main()
