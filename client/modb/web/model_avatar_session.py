"""Avatar mode on a graph of models: one browser connection drives one ModelAvatar.

The graph and its models are read once, when the session starts (on a read-only connection it
gives back at once); the walk runs in this process after that. A thread plays the avatar's frames
at the models' rate: it stands, idle, until a goal comes; a step's readout (its primitive, the
search's candidates, its constraint error) is sent when the step starts to play, and again when a
new goal re-planned it; an action's piece (a hand raised to a target) has a readout too. Another
thread synthesizes the steps ahead (ModelAvatar.fill); the avatar
guards its queue and goals with a lock of its own, so goals (the socket's thread), frames (the play
thread) and steps (the producer) need no other.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import psycopg

from modb.motion import Motion, Skeleton
from modb.provenance import as_meta, origins, sources_among
from modb.synthesis.chain import Frame, Goal, checked_goal, checked_json_goal
from modb.synthesis.from_models import EXAMPLES
from modb.synthesis.from_models import SKELETON as GRAPH_SKELETON
from modb.synthesis.model_avatar import MAX_GOALS, ModelAvatar, StepReadout
from modb.synthesis.root_motion import with_root_motion

from .avatar_messages import file_message, frame_message, sending_time
from .downloads import FORMATS

log = logging.getLogger("modb.web")

KEEP_SECONDS = 300  # a download holds the last 5 min of the walk
RECENT = 50  # the readout's medians: over the last this many steps
MAX_SEED = 2**31 - 1  # modb.synthesize_from_models's seed is an int
PRODUCER_REST_SECONDS = 0.02  # the queue full: the producer looks again after this

Send = Callable[[dict[str, Any]], None]


class ModelAvatarSession:
    """A browser connection's avatar on a graph of models: handle() takes the page's messages;
    start() sets the play thread going (the standing pose first)."""

    def __init__(
        self,
        conn: psycopg.Connection,
        send: Send,
        graph: str,
        seed: int = 0,
        goals: Sequence[Goal] = (),
    ) -> None:
        """Reads the graph on `conn` (raises what ModelAvatar raises for a graph it cannot walk:
        StoreError naming an unknown one); goals given here are the course before the walk
        starts, as `modb synth --models --to ...` takes them."""
        self._send = send
        self.graph, self.seed = graph, seed
        self._avatar = ModelAvatar(conn, graph, seed)
        for goal in goals:
            self._avatar.add_waypoint(checked_goal(goal))
        name, hierarchy, joint_map, mirror_pairs = conn.execute(GRAPH_SKELETON, [graph]).fetchone()
        self._skeleton = Skeleton.from_row(hierarchy, joint_map, mirror_pairs, name)
        self._sources = _sources(conn, graph)
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._producer: threading.Thread | None = None
        self._failed: Exception | None = None  # what stopped the producer
        # the walk's frames, for downloads: the last KEEP_SECONDS (the deque drops the oldest)
        self._walk: deque[Frame] = deque(maxlen=int(KEEP_SECONDS * self.fps) + 1)

    @property
    def fps(self) -> float:
        return float(self._avatar.fps)

    @property
    def actions(self) -> list[str]:
        """The graph's actions (its action nodes), which an "action" message may name."""
        return list(self._avatar.action_names)

    @property
    def repeated_actions(self) -> list[str]:
        """Those of its actions that repeat (a wave): an "action" message may say for how long."""
        return list(self._avatar.repeated_actions)

    def public_settings(self) -> dict[str, Any]:
        radius = self._avatar.synthesis.radius
        return {"models": self.graph, "seed": self.seed, "arrival_radius": radius}

    def start(self) -> None:
        self._producer = threading.Thread(target=self._produce, daemon=True,
                                          name="modb-model-avatar-steps")  # fmt: skip
        self._producer.start()
        self._thread = threading.Thread(target=self._play, daemon=True, name="modb-model-avatar")
        self._thread.start()

    def _produce(self) -> None:
        """The walk's pieces, ahead of playback, in a thread of their own: a step's synthesis
        (0.1-0.3 s on a busy machine) never holds back a frame."""
        try:
            while not self._stopping.is_set():
                if not self._avatar.fill():
                    self._stopping.wait(PRODUCER_REST_SECONDS)
        except Exception as e:  # a bug, or a graph the walk cannot go on in: the log has it
            if not self._stopping.is_set():
                log.exception("model avatar stopped")
                self._failed = e

    def handle(self, message: dict[str, Any]) -> None:
        kind = message.get("type") if isinstance(message, dict) else None
        if kind == "goal":
            self._goal(message)
        elif kind == "action":
            self._action(message)
        elif kind == "download":
            self._download(message)
        elif kind == "settings":
            self._send(
                {
                    "type": "refused",
                    "message": "a graph of models has no selection settings: choose motion "
                    "matching to tune them",
                }
            )
        else:
            self._send(
                {
                    "type": "refused",
                    "message": f"unknown message type {kind!r:.200}: send goal, action, download "
                    "or mode",
                }
            )

    def _goal(self, message: dict[str, Any]) -> None:
        try:
            goal = checked_json_goal((message["x"], message["z"]))
        except (KeyError, TypeError, ValueError, OverflowError):  # OverflowError: a huge integer
            why = f'a goal is {{"x": metres, "z": metres}}, got {message!r:.200}'
            self._send({"type": "refused", "message": why})
            return
        try:
            if message.get("add"):
                self._avatar.add_waypoint(goal)
            else:
                self._avatar.set_goal(goal)
            goals, index = self._avatar.goals, self._avatar.goal_index
        except ValueError as e:  # too many goals ahead
            self._send({"type": "refused", "message": str(e)})
            return
        self._send(self._goals_message(goals, index))

    def _action(self, message: dict[str, Any]) -> None:
        """{"type": "action", "primitive": a graph's action, "x", "y", "z": the target, metres,
        and for a repeated action such as a wave "seconds", how long}: performed after the
        course's goals (walk there, stop, meet the target or face it, stand)."""
        names = ", ".join(self.actions) or "none"
        primitive = message.get("primitive")
        try:
            target = checked_json_goal(tuple(message[k] for k in ("x", "y", "z")))
        except (KeyError, TypeError, ValueError, OverflowError):
            why = (f'an action is {{"primitive": one of the graph\'s actions ({names}), "x", "y", '
                   f'"z": the target in metres}}, got {message!r:.200}')  # fmt: skip
            self._send({"type": "refused", "message": why})
            return
        if not isinstance(primitive, str) or primitive not in self.actions:
            why = (f'no action {primitive!r:.100} on the graph of models "{self.graph}": its '
                   f"actions are {names}")  # fmt: skip
            self._send({"type": "refused", "message": why})
            return
        try:
            self._avatar.add_action(primitive, target, message.get("seconds"))
        except ValueError as e:  # too many goals ahead, nothing to stand with, bad seconds
            self._send({"type": "refused", "message": str(e)})
            return
        self._send(self._goals_message(self._avatar.goals, self._avatar.goal_index))

    def _goals_message(self, goals: list[Goal], index: int) -> dict[str, Any]:
        """The course: its goals (an action's: where it walks to), the one served, and the actions
        not yet done (their targets, for the page to mark)."""
        return {"type": "goals", "goals": goals, "goal_index": index,
                "actions": self._avatar.actions}  # fmt: skip

    def _play(self) -> None:
        """The avatar's frames at its rate: the standing pose first, then each new frame (standing
        frames too: it idles; where the graph has nothing to stand with it repeats its last pose,
        not sent again); a step's readout as it starts to play, the goals served as it stands."""
        avatar = self._avatar
        fps = self.fps
        try:
            skeleton_id, hierarchy, pelvis = avatar.skeleton
            self._send(
                {"type": "skeleton", "id": skeleton_id, "hierarchy": hierarchy, "pelvis": pelvis}
            )
            shown = avatar.standing
            self._send(frame_message(shown))
            frames = avatar.frames()
            idle = True  # standing, before any goal
            sent: StepReadout | None = None  # the readout the page shows
            due = time.monotonic()
            while not self._stopping.is_set():
                if self._failed is not None:
                    raise self._failed
                frame = next(frames)
                goals, index = avatar.goals, avatar.goal_index
                due = sending_time(due, time.monotonic())
                if self._stopping.wait(max(0.0, due - time.monotonic())):
                    break
                due += 1.0 / fps
                standing = frame.step == 0 or frame.rotations is shown.rotations
                if standing and not idle:  # the walk's (or an action's) last frame played
                    self._send(self._goals_message(goals, index))
                idle = standing
                if frame.rotations is shown.rotations:  # the pose shown already
                    continue
                # a new step's first frame, or a step re-planned toward a new goal
                recent = [] if standing else avatar.recent_readouts(frame.step, RECENT)
                if recent and recent[-1] is not sent:
                    self._send(step_message(recent, goals, avatar.actions))
                    sent = recent[-1]
                self._send(frame_message(frame))
                self._walk.append(frame)
                shown = frame
        except Exception as e:  # the page closed (a send failed), or a bug: the server's log has it
            if not self._stopping.is_set():
                log.exception("model avatar stopped")
                try:
                    self._send(
                        {
                            "type": "stopped",
                            "message": f"the avatar stopped: {e}; choose "
                            "the graph again to start over",
                        }
                    )
                except Exception:
                    pass

    def _download(self, message: dict[str, Any]) -> None:
        """The walk so far (its last KEEP_SECONDS), with root motion, as a file the page saves."""
        fmt = message.get("format")
        frames = list(self._walk)
        if fmt not in FORMATS or not frames:
            why = (
                f"format is one of {', '.join(FORMATS)}, got {fmt!r:.50}"
                if fmt not in FORMATS
                else "nothing walked yet: click the ground first"
            )
            self._send({"type": "refused", "message": f"no download: {why}"})
            return
        walk = Motion(
            skeleton=self._skeleton,
            fps=self.fps,
            rotations=np.stack([f.rotations for f in frames]),
            translations=np.stack([f.translations for f in frames]),
            name="walk",
            meta={"synthesized": True, "graph of models": self.graph, "seed": self.seed},
        )
        self._send(file_message(with_root_motion(walk), fmt, self._sources))

    def close(self) -> None:
        self._stopping.set()
        for thread in (self._thread, self._producer):
            if thread is not None:
                thread.join(timeout=30)


def step_message(recent: list[StepReadout], goals: list[Goal],
                 actions: list[dict[str, Any]] | None = None) -> dict[str, Any]:  # fmt: skip
    """A step's readout, and the medians of the last RECENT steps' errors (of the walk's steps:
    an action's piece is not a step of the walk). The goal being served is the step's (the
    synthesis runs a second ahead of what plays). An action's piece carries `action`: its
    target, the hand's errors (tree_error_m, refined_error_m, placed_error_m, ik_error_m where
    the kernel has IK) and keyframe_index, the frame its hand meets the target."""
    r = recent[-1]
    walked = [s for s in recent if s.action is None]

    def median(field: str) -> float | None:
        return float(np.median([getattr(s, field) for s in walked])) if walked else None

    return {
        "type": "step",
        "step": r.step,
        "node": r.node,  # the primitive
        "model": r.model,
        "first_frame": r.first_frame,
        "n_frames": r.n_frames,
        "candidates": r.candidates,  # tree nodes and leaf samples the search examined
        "error_m": r.error_m,  # the constraint error of the step played
        "tree_error_m": r.tree_error_m,  # the tree's search alone
        "random_error_m": r.random_error_m,  # the best of 300 random draws (None: an action)
        "action": r.action,
        "goal": r.goal,
        "goals": goals,
        "goal_index": len(goals) if r.goal is None else min(r.goal - 1, len(goals)),
        "actions": actions or [],
        "readout": {
            "steps": len(walked),
            "error_m_median": median("error_m"),
            "tree_error_m_median": median("tree_error_m"),
            "random_error_m_median": median("random_error_m"),
        },
    }


def checked_mode(message: dict[str, Any]) -> tuple[str | None, int, list[Goal]]:
    """(graph of models or None for motion matching, seed, goals) of a "mode" message; ValueError
    saying what is wrong."""
    models, seed, goals = message.get("models"), message.get("seed", 0), message.get("goals") or []
    if models is not None and (not isinstance(models, str) or not models or len(models) > 200):
        raise ValueError(f'"models" is a graph of models\' name or null, got {models!r:.100}')
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ValueError(f'"seed" is a whole number from 0 to {MAX_SEED}, got {seed!r:.50}')
    if not isinstance(goals, list) or len(goals) > MAX_GOALS:
        raise ValueError(f'"goals" is a list of at most {MAX_GOALS} [x, z] in metres')
    try:
        checked = [checked_json_goal(g) for g in goals]
    except (TypeError, ValueError) as e:
        raise ValueError(f'"goals": {e}') from None
    if checked and models is None:
        raise ValueError('"goals" go with "models": motion matching starts at the first click')
    return models, seed, checked


def _sources(conn: psycopg.Connection, graph: str) -> list[dict]:
    """The sources of the captured steps the graph's models learnt from, and their terms."""
    versions = [(clip, version) for clip, version, *_ in conn.execute(EXAMPLES, [graph])]
    return as_meta(sources_among(origins(conn, versions), versions))
