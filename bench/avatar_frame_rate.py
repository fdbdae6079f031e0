"""Frames at the clip's rate on the avatar's WebSocket (issue 62): the real `modb serve`, a client
that keeps walking the avatar (a new goal every few seconds, as a user clicks), in motion matching
and on a graph of models, first on the otherwise idle machine, then while BUSY processes keep every
core busy (the same run: the ratio says what the load costs).

    .venv/bin/python bench/avatar_frame_rate.py DSN GRAPH [SECONDS [idle,busy]]

Prints per mode and load: the clip's rate, the rate frames arrived at (and its share of the
clip's), the gaps between frames (p50, p99, max ms) and how many exceed 100 ms.
"""

import json
import multiprocessing
import sys
import time
from pathlib import Path

import numpy as np
import psycopg
from websockets.sync.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import serving  # noqa: E402

GOALS = [(0.0, 4.0), (3.0, 3.0), (3.0, -1.0), (-1.0, -2.0), (-3.0, 2.0)]
GOAL_EVERY_SECONDS = 3.0
MODEL_FPS = """
SELECT DISTINCT (m.data->>'fps')::float8
  FROM modb.graphs g, jsonb_each(g.data->'nodes') n, modb.models m
 WHERE g.name = %s AND g.kind = 'models' AND m.id = (n.value->>'model_id')::bigint
"""


def spin() -> None:
    while True:
        pass


def stream(address: str, graph: str | None, seconds: float) -> list[tuple[float, int]]:
    """(arrival time, frame index) of every frame received while the avatar walks."""
    frames: list[tuple[float, int]] = []
    with connect(f"ws://{address}/ws/avatar", max_size=None) as ws:
        while json.loads(ws.recv())["type"] != "ready":
            pass
        if graph is not None:
            ws.send(json.dumps({"type": "mode", "models": graph, "seed": 0}))
            while json.loads(ws.recv())["type"] != "mode":
                pass
        start = time.monotonic()
        next_goal = start
        goal = 0
        while time.monotonic() - start < seconds:
            now = time.monotonic()
            if now >= next_goal:
                x, z = GOALS[goal % len(GOALS)]
                ws.send(json.dumps({"type": "goal", "x": x, "z": z}))
                goal += 1
                next_goal += GOAL_EVERY_SECONDS
            message = json.loads(ws.recv(timeout=5))
            if message["type"] == "frame":
                frames.append((time.monotonic(), message["index"]))
    return frames


def summary(frames: list[tuple[float, int]], fps: float) -> str:
    t = np.array([f[0] for f in frames])
    t = t[t >= t[0] + 1.0]  # from a second in: the first goal's walk under way
    gaps = np.diff(t) * 1000.0
    rate = (len(t) - 1) / (t[-1] - t[0])
    return (f"{fps:g} fps clip: {rate:.1f} frames/s ({100 * rate / fps:.1f}%), gaps p50 "
            f"{np.median(gaps):.1f} p99 {np.percentile(gaps, 99):.1f} max {gaps.max():.1f} ms, "
            f"{int((gaps > 100).sum())} over 100 ms")  # fmt: skip


def main() -> None:
    dsn, graph = sys.argv[1], sys.argv[2]
    seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 30.0
    with psycopg.connect(dsn) as conn:
        (model_fps,) = conn.execute(MODEL_FPS, [graph]).fetchone()
        (snippet_fps,) = conn.execute("SELECT min(fps) FROM modb.snippets").fetchone()
    loads = sys.argv[4].split(",") if len(sys.argv) > 4 else ["idle", "busy"]
    with serving(dsn) as address:
        for load in loads:
            busy = []
            if load == "busy":
                busy = [multiprocessing.Process(target=spin, daemon=True)
                        for _ in range(multiprocessing.cpu_count())]  # fmt: skip
                for p in busy:
                    p.start()
            try:
                for mode, fps in (("motion matching", snippet_fps), (f"models {graph}", model_fps)):
                    frames = stream(address, None if mode == "motion matching" else graph, seconds)
                    print(f"{load}, {mode}: {summary(frames, float(fps))}", flush=True)
            finally:
                for p in busy:
                    p.terminate()


if __name__ == "__main__":
    main()
