"""The avatar on a graph of models: the kernel's synthesis from models (modb_kernel.model_synthesis,
which modb.synthesize_from_models runs in the server) driven step by step as goals arrive, its
frames played from a queue that is filled ahead of playback (at least QUEUE_SECONDS), so the
character never waits for a step. Without a goal it comes to rest and stands, idling, as the
synthesis does after its last goal (the graph's idle node or captured standing frames; without
either, in its last pose; at first: standing above the origin facing +Z).

With the same graph, seed and goals given before the walk starts, the frames are those of
`modb synth --models` (the same code, here with the client's numpy and scipy: equal within the
last digits)."""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg

from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import model_synthesis as MS
from modb_kernel import motion_model

from .chain import Frame, Goal

QUEUE_SECONDS = 1.0  # frames synthesized ahead of the one shown
MAX_GOALS = 100


@dataclass(frozen=True)
class StepReadout:
    """What the page shows of a step: its primitive, the search's candidates, its constraint
    error (and the tree's alone, and the best of 300 random draws)."""

    step: int
    node: str
    model: str
    first_frame: int
    n_frames: int
    candidates: int
    error_m: float
    tree_error_m: float
    random_error_m: float
    goal: int | None


class ModelAvatar:
    def __init__(self, conn: psycopg.Connection, graph: str, seed: int = 0,
                 radius: float = MS.ARRIVAL_RADIUS_M) -> None:  # fmt: skip
        self.graph_name = graph
        database = WorkerDatabase(conn)
        self.graph, models, self.rig = MS.load(database, graph)
        # the session's modb.foot_hold, as modb.synthesize_from_models reads it
        self.synthesis = MS.Synthesis(self.graph, models, self.rig, [], MS.MAX_SECONDS, seed,
                                      radius, hold_feet=MS.foot_hold_on(database))  # fmt: skip
        self.fps = self.synthesis.fps
        self.skeleton = conn.execute(
            "SELECT s.id, s.hierarchy, s.joint_map->>'pelvis' FROM modb.graphs g "
            "JOIN modb.skeletons s ON s.id = g.skeleton_id WHERE g.name = %s AND g.kind = 'models'",
            [graph],
        ).fetchone()
        self._queue: deque[Frame] = deque()
        self._shown = 0  # frames played so far
        self._read = 0  # steps whose frames are queued
        self.readouts: list[StepReadout] = []
        self.standing = self._first_pose(models)

    def _first_pose(self, models: dict[str, Any]) -> Frame:
        """The start node's model's mean motion's first frame: where the walk will begin."""
        node = MS.start_node(self.graph, np.random.default_rng(0))
        model = models[node]
        split = model.split
        zeros = np.zeros(len(model.mixture_means[0]))
        rotations, translations, _ = motion_model.frames_from_scores(
            model.model, zeros[:split], zeros[split:]
        )
        return Frame(0, 0, rotations[0], translations[0])

    @property
    def goals(self) -> list[Goal]:
        return [tuple(float(v) for v in g) for g in self.synthesis.goals]

    @property
    def goal_index(self) -> int:
        return self.synthesis.goal

    def set_goal(self, goal: Goal) -> None:
        """The new goal replaces the course (steps already queued still play)."""
        self.synthesis.goals = [_ground(goal)]
        self.synthesis.goal = 0

    def add_waypoint(self, goal: Goal) -> None:
        if len(self.synthesis.goals) - self.synthesis.goal >= MAX_GOALS:
            raise ValueError(f"at most {MAX_GOALS} goals ahead")
        self.synthesis.goals.append(_ground(goal))

    @property
    def walking(self) -> bool:
        return self.synthesis.goal < len(self.synthesis.goals)

    def _fill(self) -> None:
        """Steps toward the current goal (or, without one, pieces of standing) until
        QUEUE_SECONDS of frames wait in the queue; the synthesis keeps only the last piece's
        frames (the next seam needs them)."""
        synthesis, body = self.synthesis, self.synthesis.body
        while len(self._queue) < QUEUE_SECONDS * self.fps:
            if self.walking:
                synthesis.walk_step()
            elif synthesis.standing_source() is not None:
                if not synthesis.stop_walking():  # the stop first, where the graph has one
                    synthesis.rest()
            else:
                return
            record = synthesis.steps[-1]
            rotations, translations = body.shown[-1], body.translations[-1]
            # a step's frames carry its readout's number (from 1); standing's carry 0
            step = 0 if record.get("rest") else len(self.readouts) + 1
            first = self._shown + len(self._queue)
            for r, t in zip(rotations, translations, strict=True):
                self._queue.append(Frame(first, step, r, t))
                first += 1
            if step:
                self.readouts.append(StepReadout(
                    step, record["node"], record["model"], record["first_frame"],
                    record["n_frames"], record["candidates"], record["error_m"],
                    record["tree_error_m"], record["random_error_m"], record["goal"],
                ))  # fmt: skip
            body.drop_all_but_the_last_step()

    def frames(self) -> Iterator[Frame]:
        """The walk, a frame at a time, forever: queued frames, else the last pose again."""
        last = self.standing
        while True:
            self._fill()
            if self._queue:
                last = self._queue.popleft()
                self._shown += 1
                yield last
            else:
                yield Frame(self._shown, last.step, last.rotations, last.translations)


def _ground(goal: Goal) -> np.ndarray:
    """(x, z) of a goal given as (x, z) or (x, y, z)."""
    return np.array([goal[0], goal[-1]], dtype=np.float64)
