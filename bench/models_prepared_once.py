"""Models prepared once per process (issue 62, BENCHMARKS.md "Models prepared once per process"):
the first and second `modb.synthesize_from_models` call of one session, a new session's first
(the server's backends each keep their own), and the avatar page's mode switch to the graph of
models against the real `modb serve`: the time from the page's "mode" message to the first frame,
on a new server at once (it prepares the page's first graph as it starts: the switch waits for
that), on a new server 5 s after it started (as a user opening the page), again on the same
connection, and on a new connection (a browser session of its own) of that server (warm).

    .venv/bin/python bench/models_prepared_once.py DSN GRAPH [ROUNDS]
"""

import json
import statistics
import sys
import time
from pathlib import Path

import websocket

from modb.database.connection import connect

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import serving  # noqa: E402

GOALS = [[0.0, 6.0], [6.0, 8.0]]
OPENED_AFTER_S = 5.0  # a user opens the page this long after the server started
SECONDS = 10.0
SYNTHESIZE = "SELECT n_frames FROM modb.synthesize_from_models(%s, %s::float8[], %s, 0)"


def call_times(dsn: str, graph: str) -> tuple[float, float, float]:
    """(first, second) call of one session and the first of a new session, seconds."""
    times = []
    for calls in (2, 1):
        with connect(dsn) as conn:
            conn.execute("SELECT 1 FROM modb.graphs LIMIT 1")  # the kernel imported: not timed
            for _ in range(calls):
                t = time.perf_counter()
                conn.execute(SYNTHESIZE, [graph, GOALS, SECONDS]).fetchall()
                times.append(time.perf_counter() - t)
    return tuple(times)


def until(ws: websocket.WebSocket, kind: str) -> dict:
    while True:
        message = json.loads(ws.recv())
        if message["type"] == kind:
            return message
        if message["type"] in ("refused", "stopped"):
            raise RuntimeError(message)


def mode_switch(ws: websocket.WebSocket, graph: str) -> float:
    """Seconds from the "mode" message to the graph of models to its first frame (the standing
    pose), then back to motion matching."""
    t = time.perf_counter()
    ws.send(json.dumps({"type": "mode", "models": graph, "seed": 0}))
    until(ws, "mode")
    until(ws, "frame")
    seconds = time.perf_counter() - t
    ws.send(json.dumps({"type": "mode", "models": None}))
    until(ws, "mode")
    return seconds


def page(address: str) -> websocket.WebSocket:
    ws = websocket.create_connection(f"ws://{address}/ws/avatar", origin=f"http://{address}")
    until(ws, "ready")
    return ws


def main(dsn: str, graph: str, rounds: int) -> None:
    calls = [call_times(dsn, graph) for _ in range(rounds)]
    for name, k in (("first call", 0), ("second call, same session", 1),
                    ("first call, new session", 2)):  # fmt: skip
        values = [c[k] for c in calls]
        print(f"{name}: median {statistics.median(values):.3f} s "
              f"({', '.join(f'{v:.3f}' for v in values)})")  # fmt: skip
    cold, later, again, other = [], [], [], []
    for _ in range(rounds):
        with serving(dsn) as address:
            first = page(address)
            cold.append(mode_switch(first, graph))
            first.close()
        with serving(dsn) as address:
            time.sleep(OPENED_AFTER_S)
            ws = page(address)
            later.append(mode_switch(ws, graph))
            again.append(mode_switch(ws, graph))
            second = page(address)
            other.append(mode_switch(second, graph))
            ws.close()
            second.close()
    rows = (("mode switch, new server at once", cold),
            (f"new server, page opened {OPENED_AFTER_S:g} s after", later),
            ("again, same page", again), ("warm server, another page", other))  # fmt: skip
    for name, values in rows:
        print(f"{name}: median {statistics.median(values):.3f} s "
              f"({', '.join(f'{v:.3f}' for v in values)})")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 3)
