"""The avatar on a graph of models: the kernel's synthesis from models (modb_kernel.model_synthesis,
which modb.synthesize_from_models runs in the server) driven piece by piece as goals arrive. Its
frames wait in a queue filled ahead of playback (about QUEUE_SECONDS) by `fill`, which a producer
thread calls, so playback never waits for a step. Without a goal it comes to rest and stands,
idling, as the synthesis does after its last goal (the graph's idle node or captured standing
frames; without either, in its last pose; at first: standing above the origin facing +Z).

A new goal is answered from the piece playing, not a queue later: the step playing is planned
again toward it from where it began (the same foot planted) and its frames from a moment after the
one playing are blended into the new step's; a piece of standing is cut there and the start blends
from it. The queued pieces after it are dropped and planned again (each queued piece keeps the
synthesis as it stood before and after it). So the walk turns toward a new goal within a few tenths
of a second of the click.

An action (a graph's action node, e.g. raise_right_hand, with a target for the hand) joins the
course as a waypoint does: the character walks to within reach of the target, stops, comes to
rest, performs it (model_actions.perform: the hand meets the target at the keyframe) and stands.
An action's piece is never planned again once queued: a new goal while it plays waits for its end.

With the same graph, seed and goals given before the walk starts, the frames are those of
`modb synth --models` (the same code, here with the client's numpy and scipy: equal within the
last digits)."""

from __future__ import annotations

import copy
import threading
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg

from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import model_actions, motion_model
from modb_kernel import model_synthesis as MS
from modb_kernel.step_search import hip_heading

from .blend import CROSS_FADE_SECONDS, cross_fade
from .chain import Frame, Goal

QUEUE_SECONDS = 1.0  # frames synthesized ahead of the one shown
MAX_GOALS = 100
# A replan keeps at least this much of what is queued, so the next piece is ready before the queue
# runs dry (a step takes 60-190 ms to synthesize on an idle machine), and at least LEAD_PER_PIECE
# times the recent pieces' synthesis (a busy machine takes longer). A step planned again needs less:
# when it comes too late to blend into, the old one plays on (no gap, a later answer).
REPLAN_LEAD_SECONDS = 0.15
LEAD_PER_PIECE = 2.0
REDO_LEAD_PER_PIECE = 1.25


@dataclass(frozen=True)
class StepReadout:
    """What the page shows of a step: its primitive, the search's candidates, its constraint
    error (and the tree's alone, and the best of 300 random draws). An action's has no random
    draws (None) and `action`: its target, the hand's error after the tree, the refinement, the
    placement and IK (where the kernel has it), and the frame of its keyframe (the avatar's
    numbering, as the page's frames carry it)."""

    step: int
    node: str
    model: str
    first_frame: int
    n_frames: int
    candidates: int
    error_m: float
    tree_error_m: float
    random_error_m: float | None
    goal: int | None
    action: dict[str, Any] | None = None


@dataclass(eq=False)
class _Piece:
    """A step or a piece of standing in the queue: its frames' indices, the readouts up to it, and
    the synthesis as it stood before and after it (a replan goes on from a copy of one)."""

    first: int
    n_frames: int
    readouts: int
    standing: bool
    before: MS.Synthesis
    after: MS.Synthesis
    action: dict[str, Any] | None = None  # an action's piece: its entry in ModelAvatar._actions

    @property
    def end(self) -> int:
        return self.first + self.n_frames


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
        # What every copy of the synthesis shares: the models and what is read from them.
        self._shared = [models, self.graph, self.rig, self.synthesis.types,
                        self.synthesis.successors, self.synthesis.floors]  # fmt: skip
        self._lock = threading.Lock()  # the queue and the goals: fill() and the page's thread
        self._queue: deque[Frame] = deque()
        self._pieces: deque[_Piece] = deque()  # the queued pieces, oldest first
        self._shown = 0  # frames played so far
        self._changes: list[tuple[str, Any]] = []  # goals set or added, not yet planned
        self._goals: list[np.ndarray] = []  # the course as the page sees it
        # the actions asked for and not yet played to their end: {primitive, target, goal (its
        # index in _goals), course (_course when asked), queued (its piece is in the queue)}
        self._actions: list[dict[str, Any]] = []
        self._course = 0  # how many times the course was replaced (set_goal)
        self.action_names = sorted(n for n, t in self.synthesis.types.items() if t == "action")
        # a repeated motion (a wave: its repetition's first and last turn) goes on for the seconds
        # asked; a reach does not
        self.repeated_actions = [n for n in self.action_names if models[n].repetition is not None]
        self._piece_seconds = 0.0  # the recent pieces' synthesis time, seconds
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
        with self._lock:
            return [tuple(float(v) for v in g) for g in self._goals]

    @property
    def goal_index(self) -> int:
        """The goal the piece playing serves (0 once a new goal is set)."""
        with self._lock:
            if any(kind == "set" for kind, _ in self._changes):
                return 0
            playing = self._playing()
            synthesis = self.synthesis if playing is None else playing.after
            return min(synthesis.goal, len(self._goals))

    def recent_readouts(self, step: int, n: int) -> list[StepReadout]:
        """The readouts of steps step - n + 1 to step (the last is that step's; [] when a replan
        took it back meanwhile)."""
        with self._lock:
            if not 0 < step <= len(self.readouts):
                return []
            return self.readouts[max(0, step - n) : step]

    @property
    def actions(self) -> list[dict[str, Any]]:
        """The actions asked for and not yet done (their piece not played to its end): primitive,
        target [x, y, z], goal (the index of where it is performed in `goals`) and, where asked,
        seconds (how long a repeated one goes on)."""
        with self._lock:
            return [{k: a[k] for k in ("primitive", "target", "goal", "seconds") if k in a}
                    for a in self._actions]  # fmt: skip

    def set_goal(self, goal: Goal) -> None:
        """The new goal replaces the course, from the piece playing on (an action queued to
        play already plays)."""
        with self._lock:
            self._goals = [_ground(goal)]
            self._changes.append(("set", self._goals[0]))
            self._course += 1
            self._actions = [a for a in self._actions if a["queued"]]

    def add_waypoint(self, goal: Goal) -> None:
        with self._lock:
            self._room_ahead()
            self._goals.append(_ground(goal))
            self._changes.append(("add", self._goals[-1]))

    def add_action(self, primitive: str, target: tuple[float, float, float],
                   seconds: float | None = None) -> None:  # fmt: skip
        """The action after the course's goals: walk to within reach of the target, stop, perform
        it (the hand at the target at its keyframe; a wave faces it, for `seconds` when given),
        stand. ValueError saying why it cannot."""
        asked = {"primitive": primitive, "target": list(target)}
        if seconds is not None:
            asked["seconds"] = seconds
        checked = model_actions.checked([asked], 0, self.action_names)[0]
        with self._lock:
            if self.synthesis.standing_source() is None:
                raise ValueError(
                    f'the graph "{self.graph_name}" has nothing to stand with (no idle node or '
                    "captured standing): it cannot perform actions"
                )
            self._room_ahead()
            self._goals.append(checked["target"][[0, 2]])
            self._actions.append({"primitive": primitive, "target": checked["target"].tolist(),
                                  "goal": len(self._goals) - 1, "course": self._course,
                                  "queued": False, **({} if seconds is None else {
                                      "seconds": checked["seconds"]})})  # fmt: skip
            self._changes.append(("action", checked))

    def _room_ahead(self) -> None:
        reached = 0 if self._changes else min(self.synthesis.goal, len(self._goals))
        if len(self._goals) - reached >= MAX_GOALS:
            raise ValueError(f"at most {MAX_GOALS} goals ahead")

    def fill(self) -> bool:
        """Plans the goals that came since, then adds a piece when the queue is short; whether
        it did anything (a producer thread calls this in a loop, resting when it did not)."""
        with self._lock:
            changes, self._changes = self._changes, []
            if changes:
                # every queued piece's states take the new course, so whichever a replan goes on
                # from (now or at a later change) holds every change so far, once
                for piece in self._pieces:
                    _change_goals(piece.before, changes)
                    _change_goals(piece.after, changes)
            redo = self._replan(changes) if changes else None
            if redo is None and len(self._queue) >= QUEUE_SECONDS * self.fps:
                return bool(changes)
            synthesis, first = self.synthesis, self._shown + len(self._queue)
        if redo is not None:
            self._redo(*redo, changes)
            return True
        before = self._copy(synthesis)
        started = time.perf_counter()
        frames, record = self._next_piece(synthesis)  # the slow part, unlocked
        if frames is None:
            return bool(changes)
        with self._lock:
            self._took(time.perf_counter() - started)
            self._queue_piece(first, frames, record, before, self._copy(synthesis))
        return True

    def _took(self, seconds: float) -> None:
        """A piece's synthesis time, into the recent pieces' (a moving average)."""
        self._piece_seconds += 0.3 * (seconds - self._piece_seconds)

    def _lead(self, per_piece: float = LEAD_PER_PIECE) -> int:
        """Frames after the one playing that a replan leaves as they are: time to make the next."""
        return int(round(max(REPLAN_LEAD_SECONDS, per_piece * self._piece_seconds) * self.fps))

    def _queue_piece(self, first: int, frames, record: dict[str, Any], before: MS.Synthesis,
                     after: MS.Synthesis, step: int | None = None) -> None:  # fmt: skip
        """A piece's frames (from frame `first` on), its readout and its piece, queued."""
        standing = bool(record.get("rest"))
        # a step's frames carry its readout's number (from 1); standing's carry 0
        step = 0 if standing else step or len(self.readouts) + 1
        for k, (r, t) in enumerate(zip(*frames, strict=True)):
            self._queue.append(Frame(first + k, step, r, t))
        entry = None
        if not standing:
            done = _action_readout(record, first) if record.get("action") else None
            self.readouts.append(StepReadout(
                step, record["node"], record["model"], record["first_frame"],
                record["n_frames"], record["candidates"], record["error_m"],
                record["tree_error_m"], record.get("random_error_m"), record["goal"], done,
            ))  # fmt: skip
            if done is not None:
                entry = next((a for a in self._actions if a["goal"] == record["goal"] - 1
                              and a["course"] == self._course), None)  # fmt: skip
                if entry is not None:
                    entry["queued"] = True
        n = len(frames[0])
        self._pieces.append(_Piece(first, n, len(self.readouts), standing, before, after, entry))

    def _next_piece(self, synthesis: MS.Synthesis) -> tuple[Any, dict[str, Any]]:
        """((rotations, translations) shown, its record) of the next piece: a step toward the
        current goal or, without one, a piece of standing; (None, {}) when there is nothing to
        add (no goal, and nothing to stand with: the last pose holds)."""
        body = synthesis.body
        if synthesis.act_step():  # an action reached: its stop, rest, itself, standing after it
            pass
        elif synthesis.goal < len(synthesis.goals):
            synthesis.walk_step()
        elif synthesis.standing_source() is not None:
            if not synthesis.stop_walking():  # the stop first, where the graph has one
                synthesis.rest()
        else:
            return None, {}
        record = synthesis.steps[-1]
        if record.get("action"):  # its report's record too: the errors, the keyframe
            record = {**record, "report": synthesis.actions[-1]}
        frames = (body.shown[-1], body.translations[-1])
        body.drop_all_but_the_last_step()
        del synthesis.steps[:-1]  # an avatar reads the last step's record only
        del synthesis.actions[:]
        synthesis.notes.clear()  # nor the report's notes (each piece's states copy them)
        return frames, record

    def _playing(self) -> _Piece | None:
        """The queued piece whose frame plays next (None when every queued frame has played)."""
        for piece in self._pieces:
            if piece.end > self._shown:
                return piece
        return None

    def _replan(self, changes: list[tuple[str, Any]]):
        """The goals changed, from the piece playing on. The step that plays a moment after the
        frame playing (_lead), where enough of it is left, is planned again from
        where it began and blended into from that moment: returns (that piece, that frame) for
        _redo, which does it outside the lock.
        Else (None) the queue after the piece playing (or the next, when little of it is left)
        is dropped here and the synthesis goes on from after it, a piece of standing cut a
        moment after the frame playing: the start blends from there."""
        start = self._shown + self._lead(REDO_LEAD_PER_PIECE)
        blend = int(round(CROSS_FADE_SECONDS * self.fps))
        pieces = list(self._pieces)
        at = next((k for k, p in enumerate(pieces) if p.first <= start < p.end), None)
        if at is not None and start + blend + 2 > pieces[at].end and at + 1 < len(pieces):
            at, start = at + 1, pieces[at + 1].first  # too late in its step: the next one, whole
        # a seam needs the step's own last two frames; an action plays to its end
        if (at is not None and not pieces[at].standing and pieces[at].action is None
                and start + blend + 2 <= pieces[at].end):  # fmt: skip
            return pieces[at], start
        self._replan_after(changes)
        return None

    def _replan_after(self, changes: list[tuple[str, Any]]) -> None:
        """The goals changed after the piece playing (or the next, when little of it is left):
        what is queued after it dropped, the synthesis back to where it stood after it."""
        lead = self._lead()
        keep = None
        for piece in self._pieces:
            if piece.end > self._shown + lead or piece is self._pieces[-1]:
                keep = piece
                break
        if keep is None:  # nothing queued: the synthesis goes on from where it stands
            _change_goals(self.synthesis, changes)
            return
        n = max(self._shown + lead + 1 - keep.first, 2)  # the standing frames to keep: a seam
        if keep.standing and n < keep.n_frames:  # joins the last two
            self._cut(keep, n)
        self._drop_after(keep)
        self.synthesis = self._copy(keep.after)

    def _drop_after(self, keep: _Piece) -> None:
        """The pieces queued after `keep` dropped, with their frames and readouts."""
        while self._pieces[-1] is not keep:
            self._unqueue(self._pieces.pop())
        while self._queue and self._queue[-1].index >= keep.end:
            self._queue.pop()
        del self.readouts[keep.readouts :]

    def _redo(self, piece: _Piece, start: int, changes: list[tuple[str, Any]]) -> None:
        """The step planned again toward the new goals from where it began, its frames from
        `start` on faded into the new ones over CROSS_FADE_SECONDS (both leave the same pose, the
        same foot planted). When playback passed `start` meanwhile, or the new step is too short
        to fade into, the old one plays to its end and the walk goes on from there."""
        synthesis = self._copy(piece.before)  # the new course in it already (fill)
        before = self._copy(synthesis)
        started = time.perf_counter()
        frames, record = self._next_piece(synthesis)  # the slow part, unlocked
        after = self._copy(synthesis)
        with self._lock:
            self._took(time.perf_counter() - started)
            b = start - piece.first
            n = 0 if frames is None else min(int(round(CROSS_FADE_SECONDS * self.fps)),
                                             len(frames[0]) - b - 2)  # fmt: skip
            if self._shown > start or n < 2 or piece not in self._pieces or record.get("rest"):
                self._replan_after(changes)
                return
            old = [f for f in self._queue if piece.first <= f.index < piece.end]
            old = old[start - old[0].index :]  # from `start` on
            ahead = tuple(np.stack([getattr(f, a) for f in old[:n]])
                          for a in ("rotations", "translations"))  # fmt: skip
            rotations, translations = cross_fade(ahead, (frames[0][b:], frames[1][b:]), 0, n)
            step = old[0].step  # the readout number the page knows the step by
            while (dropped := self._pieces.pop()) is not piece:  # it and those after it
                self._unqueue(dropped)
            while self._queue and self._queue[-1].index >= start:
                self._queue.pop()
            del self.readouts[piece.readouts - 1 :]
            self.synthesis = synthesis
            self._queue_piece(start, (rotations, translations), record, before, after, step)
            self._pieces[-1].first, self._pieces[-1].n_frames = piece.first, len(frames[0])

    def _unqueue(self, piece: _Piece) -> None:
        """A queued piece dropped: its action (if it is one) is performed again from the state
        the synthesis goes on from, unless the course was replaced since it was asked for."""
        if piece.action is not None:
            piece.action["queued"] = False
            if piece.action["course"] != self._course:
                self._actions.remove(piece.action)

    def _cut(self, piece: _Piece, n: int) -> None:
        """The piece of standing ends after its first n frames: what is queued of it, and the
        synthesis after it (its last frames, where its feet stand and it faces)."""
        while self._queue and self._queue[-1].index >= piece.first + n:
            self._queue.pop()
        body, rig = piece.after.body, self.rig
        drop = piece.n_frames - n
        for frames in (body.rotations, body.translations, body.shown):
            frames[-1] = frames[-1][:-drop]
        end = rig.positions(body.rotations[-1][-1:], body.translations[-1][-1:])[0]
        body.heading = float(hip_heading(end, rig.left_hip, rig.right_hip))
        body.feet = {side: end[joint][[0, 2]] for side, joint in rig.ankle.items()}
        piece.n_frames = n

    def _copy(self, synthesis: MS.Synthesis) -> MS.Synthesis:
        """A copy to go on from: its own body, feet, seams and random state, the models shared."""
        shared = [*self._shared, synthesis.captured, getattr(synthesis, "_legs", None)]
        return copy.deepcopy(synthesis, {id(x): x for x in shared if x is not None})

    def frames(self) -> Iterator[Frame]:
        """The walk, a frame at a time, forever: queued frames, else the last pose again (fill()
        adds them, from another thread)."""
        last = self.standing
        while True:
            with self._lock:
                if self._queue:
                    last = self._queue.popleft()
                    self._shown += 1
                    while self._pieces and self._pieces[0].end <= self._shown:
                        played = self._pieces.popleft()  # a replan goes on from self.synthesis
                        if any(a is played.action for a in self._actions):  # done: its target goes
                            self._actions.remove(played.action)
                    frame = last
                else:
                    frame = Frame(self._shown, last.step, last.rotations, last.translations)
            yield frame


def _ground(goal: Goal) -> np.ndarray:
    """(x, z) of a goal given as (x, z) or (x, y, z)."""
    return np.array([goal[0], goal[-1]], dtype=np.float64)


def _action_readout(record: dict[str, Any], first: int) -> dict[str, Any]:
    """An action piece's readout: its primitive, target, the hand's errors after each stage (the
    kernel's keys ending in _error_m: tree, refined, placed, ik where it has IK) and its
    keyframe as the avatar's frame index (its piece's frames begin at `first`)."""
    report = record["report"]
    out = {"primitive": record["node"], "target": report.get("target"),
           "cut": bool(report.get("cut"))}  # fmt: skip
    out.update({k: v for k, v in report.items() if k.endswith("_error_m")})
    if report.get("keyframe_frame") is not None:
        out["keyframe_index"] = first + report["keyframe_frame"] - record["first_frame"]
    return out


def _change_goals(synthesis: MS.Synthesis, changes: list[tuple[str, Any]]) -> None:
    """The goals set ("set": the course replaced), added, or actions added ("action": as
    model_actions.checked gives them), in order, on this synthesis."""
    for kind, goal in changes:
        if kind == "set":
            synthesis.set_goal(goal)
        elif kind == "action":
            if not synthesis.goals and not synthesis.body.rotations:
                # the first piece's state before it, with no frames and no goal to come from:
                # nothing goes on from it (only a step's is planned again, and the first stands)
                continue
            synthesis.add_goal(goal["target"][[0, 2]], goal)
        else:
            synthesis.add_goal(goal)
