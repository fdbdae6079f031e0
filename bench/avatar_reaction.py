"""How soon the avatar answers a new goal (issue 62): the real `modb serve`, a WebSocket client
that walks it toward a goal far ahead, waits until it walks straight, then sends a goal 3 m to one
side (as a click does) and times the hips' heading turning 5 degrees toward it for good
(tests/support/reaction.py, the avatar page's test's measure; the poses by the kernel's forward
kinematics from the frames received). Both modes, CLICKS goals each, alternating sides.

    .venv/bin/python bench/avatar_reaction.py DSN GRAPH [CLICKS]

Prints per mode the reactions (s): each, median and max, and in motion matching when the snippet
chosen toward the new goal arrived.
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import psycopg
from websockets.sync.client import connect

from modb_kernel.kinematics import world_positions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import serving  # noqa: E402
from support.reaction import (  # noqa: E402
    ahead_and_aside,
    hips_heading,
    mean_heading,
    turn_reaction,
    walks_straight,
)

JOINT_MAP = "SELECT joint_map FROM modb.skeletons WHERE id = %s"


class Walk:
    """The frames received (arrival time, pelvis on the ground, hips' heading) and the choices."""

    def __init__(self, ws, dsn: str) -> None:
        self.ws, self.dsn = ws, dsn
        self.t: list[float] = []
        self.pelvis: list[np.ndarray] = []
        self.heading: list[float] = []
        self.choices: list[tuple[float, list]] = []  # (arrival, target)
        self.rig = None

    def receive(self, seconds: float) -> None:
        until = time.monotonic() + seconds
        while (left := until - time.monotonic()) > 0:
            try:
                m = json.loads(self.ws.recv(timeout=left))
            except TimeoutError:  # nothing more came (it stands, waiting for a goal)
                return
            now = time.monotonic()
            if m["type"] == "skeleton":
                self._skeleton(m)
            elif m["type"] == "choice":
                self.choices.append((now, m["target"]))
            elif m["type"] == "frame" and self.rig is not None:
                parents, offsets, translated, at = self.rig
                p = world_positions(parents, offsets, np.array([m["rotations"]]),
                                    np.array([m["translations"]]), translated)[0]  # fmt: skip
                self.t.append(now)
                self.pelvis.append(p[at["pelvis"]][[0, 2]])
                self.heading.append(float(hips_heading(p, at["left_hip"], at["right_hip"])))

    def _skeleton(self, m: dict) -> None:
        h = m["hierarchy"]
        with psycopg.connect(self.dsn) as conn:
            (joint_map,) = conn.execute(JOINT_MAP, [m["id"]]).fetchone()
        names = [j["name"] for j in h["joints"]]
        at = {k: names.index(v) for k, v in joint_map.items() if v in names}
        self.rig = ([j["parent"] for j in h["joints"]], [j["offset"] for j in h["joints"]],
                    h["translated"], at)  # fmt: skip

    def facing(self) -> tuple[np.ndarray, float]:
        """The pelvis now and the hips' mean heading over the last second."""
        t = np.array(self.t)
        return self.pelvis[-1], mean_heading(np.array(self.heading)[t >= t[-1] - 1.0])

    def straight(self) -> bool:
        return walks_straight(np.array(self.t), np.array(self.heading))


def goal(ws, x: float, z: float) -> None:
    ws.send(json.dumps({"type": "goal", "x": float(x), "z": float(z)}))


def clicks(address: str, dsn: str, graph: str | None, n: int) -> tuple[list, list]:
    with connect(f"ws://{address}/ws/avatar", max_size=None) as ws:
        walk = Walk(ws, dsn)
        walk.receive(0.5)
        if graph is not None:
            ws.send(json.dumps({"type": "mode", "models": graph, "seed": 0}))
            walk.receive(3.0)
        goal(ws, 0.0, 6.0)
        walk.receive(2.0)
        reactions, arrivals = [], []
        for k in range(n):
            pelvis, facing = walk.facing()
            goal(ws, *ahead_and_aside(pelvis, facing, 8.0, 0.0))
            walk.receive(1.0 + 0.13 * k)  # other moments of a step
            for _ in range(30):
                if walk.straight():
                    break
                walk.receive(0.1)
            pelvis, facing = walk.facing()
            target = ahead_and_aside(pelvis, facing, 1.0, 3.0 if k % 2 == 0 else -3.0)
            clicked = time.monotonic()
            goal(ws, *target)
            walk.receive(1.5)
            poses = np.array(walk.t), np.array(walk.heading), np.array(walk.pelvis)
            reactions.append(turn_reaction(*poses, clicked, tuple(target)))
            came = [a for a, tg in walk.choices if a >= clicked and np.allclose(tg, target)]
            arrivals.append(came[0] - clicked if came else np.inf)
    return reactions, arrivals


def main() -> None:
    dsn, graph = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 8
    with serving(dsn) as address:
        for mode in (None, graph):
            reactions, arrivals = clicks(address, dsn, mode, n)
            r = np.array(reactions)
            print(f"{mode or 'motion matching'}: heading turned after {np.round(r, 2).tolist()} s: "
                  f"median {np.median(r):.2f}, max {r.max():.2f}; "
                  + ("" if mode else f"new snippet after {np.round(arrivals, 2).tolist()} s"),
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
