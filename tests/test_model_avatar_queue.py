"""The models avatar's queue (client/modb/synthesis/model_avatar.py) under goals that come at any
moment while playback moves on, on a stand-in synthesis (no database: steps of 14-20 frames toward
the current goal, pieces of standing without one): the frames stay contiguous, the pieces match the
queue, the readouts are numbered 1..n and every queued step has one, playback never skips a frame,
and after every goal the synthesis walks the course the page shows (none lost by a quick second
click)."""

from __future__ import annotations

import copy
import random
import threading
from collections import deque

import numpy as np
import pytest

from modb.synthesis import model_avatar as MA


class Course:
    """What the avatar reads of a synthesis: goals, the goal index, a step's record."""

    def __init__(self, seed: int) -> None:
        self.goals: list = []
        self.goal, self.reached, self.closest = 0, {}, np.inf
        self.rng = random.Random(seed)
        self.frames = 0

    def set_goal(self, goal) -> None:  # as model_synthesis.Synthesis's (no actions here)
        self.goals, self.goal, self.reached, self.closest = [goal], 0, {}, np.inf

    def add_goal(self, goal, action=None) -> None:
        self.goals.append(goal)

    def standing_source(self) -> str:
        return "idle"

    def stop_walking(self) -> bool:
        return False


class StandIn(MA.ModelAvatar):
    """ModelAvatar with Course for its synthesis: steps and standing made up, timed as told."""

    def __init__(self, seed: int, playing) -> None:  # no database: the queue's own state only
        self.fps = 30.0
        self.synthesis = Course(seed)
        self._shared = []
        self._lock = threading.Lock()
        self._queue, self._pieces, self._shown = deque(), deque(), 0
        self._changes, self._goals, self._piece_seconds = [], [], 0.0
        self._actions, self._course = [], 0  # no actions here
        self.readouts = []
        self.standing = MA.Frame(0, 0, np.zeros((1, 4)), np.zeros((1, 3)))
        self.playing = playing  # playback moving on while a piece is made, unlocked
        self.seconds = 0.1

    def _copy(self, synthesis):
        return copy.deepcopy(synthesis)

    def _took(self, seconds: float) -> None:
        super()._took(self.seconds)

    def _next_piece(self, s: Course):
        self.playing()
        walking = s.goal < len(s.goals)
        n = s.rng.randint(14, 20) if walking else 30
        record = {"rest": True} if not walking else {
            "node": "step", "model": "m", "first_frame": s.frames, "n_frames": n,
            "candidates": 1, "error_m": 0.0, "tree_error_m": 0.0, "random_error_m": 0.0,
            "goal": s.goal + 1}  # fmt: skip
        if walking and s.rng.random() < 0.3:
            s.goal += 1  # reached
        s.frames += n
        rotations = np.zeros((n, 1, 4))
        rotations[..., 0] = 1.0
        return (rotations, np.zeros((n, 1, 3))), record

    def _cut(self, piece, n: int) -> None:
        while self._queue and self._queue[-1].index >= piece.first + n:
            self._queue.pop()
        piece.after.frames -= piece.n_frames - n
        piece.n_frames = n


def consistent(a: StandIn) -> None:
    queued = [f.index for f in a._queue]
    assert queued == list(range(a._shown, a._shown + len(queued))), "a gap in the queue"
    pieces = list(a._pieces)
    assert all(p.end == q.first for p, q in zip(pieces, pieces[1:])), "a gap between pieces"
    if pieces:
        assert pieces[-1].end == a._shown + len(queued), "the pieces and the queue disagree"
    assert [r.step for r in a.readouts] == list(range(1, len(a.readouts) + 1))
    assert all(f.step <= len(a.readouts) for f in a._queue), "a queued step without its readout"


def course_of(synthesis: Course) -> list[tuple[float, float]]:
    return [tuple(float(v) for v in g) for g in synthesis.goals]


@pytest.mark.parametrize("seed", range(6))
def test_goals_at_any_moment_keep_the_queue_whole_and_the_course_the_pages(seed):
    rnd = random.Random(seed)
    played = []
    avatar = StandIn(seed, lambda: played.extend(next(frames) for _ in range(rnd.choice(
        [0, 0, 1, 3, 8]))))  # fmt: skip
    frames = avatar.frames()
    for _ in range(1500):
        avatar.seconds = rnd.choice([0.05, 0.1, 0.2, 0.3])
        r = rnd.random()
        if r < 0.05:
            goal = (rnd.uniform(-9, 9), rnd.uniform(-9, 9))
            avatar.add_waypoint(goal) if r < 0.02 else avatar.set_goal(goal)
            avatar.fill()
            # the synthesis walks the course the page shows, from a goal of it on
            shown = [tuple(float(v) for v in g) for g in avatar.goals]
            assert course_of(avatar.synthesis) == shown
        elif r < 0.5:
            avatar.fill()
        else:
            played.append(next(frames))
        consistent(avatar)
    index = [f.index for f in played]
    assert all(b in (a, a + 1) for a, b in zip(index, index[1:])), "playback skipped a frame"
    assert len(set(index)) > 500  # it walked
