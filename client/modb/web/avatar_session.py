"""Avatar mode: one browser connection drives one Avatar on a database session of its own.

The page sends goals and settings (JSON over the WebSocket); the session plays the Avatar's frames at the
source rate and sends each one, with a readout after every selection. Settings are SET on this session's
own connection (never a shared one), so two pages tune independently. Settings are checked on another
connection first: a bad value is refused with a message and the walk goes on with the previous ones.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from typing import Any

import numpy as np
import psycopg

from modb.synthesis.avatar import Avatar, Choice, Frame, NoContinuation, Settings, checked_goal
from modb.database.connection import connect
from modb.synthesis.placement import Placement

log = logging.getLogger("modb.web")

# The knobs the panel tunes (a subset of modb.match_knobs(); modb.graph is its own setting).
TUNABLE_KNOBS = (
    "position_threshold",
    "angle_threshold",
    "velocity_threshold",
    "angular_velocity_threshold",
    "norm",
    "joints",
    "velocity_terms",
)
MAX_LEAD_TIME = (
    2.0  # seconds: longer than any snippet, the next query would start before this one plays
)
RECENT = 50  # the readouts summarise the last this many selections
STATEMENT_TIMEOUT = "10s"  # an avatar's query that takes longer stops it (and frees its slot)

Send = Callable[[dict[str, Any]], None]
Check = Callable[[Settings], None]


class SettingsRefused(ValueError):
    pass


def settings_from(message: dict[str, Any], current: Settings) -> Settings:
    """The settings a page asked for, from a {"type": "settings", ...} message (missing keys keep theirs)."""
    unknown = sorted(
        set(message)
        - {"type", "profile", "graph", "collection", "lead_time", "arrival_radius", "knobs"}
    )
    if unknown:
        raise SettingsRefused(f"unknown setting {unknown[0]!r}")
    asked = message.get("knobs") or {}
    if not isinstance(asked, dict):
        raise SettingsRefused(f"knobs is an object of knob: value, got {asked!r}")
    knobs = dict(current.knobs)
    for knob, value in asked.items():
        if knob not in TUNABLE_KNOBS:
            raise SettingsRefused(
                f"unknown knob {knob!r}: the panel tunes {', '.join(TUNABLE_KNOBS)}"
            )
        if value is None or value == "":
            knobs.pop(knob, None)  # back to the profile's
        elif isinstance(value, (str, int, float)) and not isinstance(value, bool):
            knobs[knob] = str(value)
        else:
            raise SettingsRefused(f"knob {knob} takes a text or number, got {value!r}")
    changes: dict[str, Any] = {"knobs": knobs}
    for name in ("profile", "graph", "collection"):
        if name in message:
            value = message[name]
            if value is not None and not isinstance(value, str):
                raise SettingsRefused(f"{name} is a name, got {value!r}")
            changes[name] = value or (None if name != "profile" else "default")
    for name, unit, least, most in (
        ("lead_time", "seconds", 0.0, MAX_LEAD_TIME),
        ("arrival_radius", "metres", 0.01, 10.0),
    ):
        if name in message:
            value = message[name]
            number = (
                not isinstance(value, bool)
                and isinstance(value, (int, float))
                and math.isfinite(value)
            )
            if not number or not least <= value <= most:
                raise SettingsRefused(f"{name} must be {least:g}-{most:g} {unit}, got {value!r}")
            changes[name] = float(value)
    return replace(current, **changes)


def check_settings(conn: psycopg.Connection, settings: Settings) -> None:
    """Resolves the settings as a selection would (modb.match_plan, the collection) in a transaction of its
    own, so that the database says what is wrong before any avatar uses them."""
    try:
        with conn.transaction():
            for knob, value in settings.session_knobs().items():
                conn.execute("SELECT set_config(%s, %s, true)", [f"modb.{knob}", value])
            conn.execute(
                "SELECT modb.match_plan(%s), modb.check_request(NULL, '{0,1}', 1, %s)",
                [settings.profile, settings.collection],
            )
    except psycopg.Error as e:
        hint = f" ({e.diag.message_hint})" if e.diag.message_hint else ""
        raise SettingsRefused(f"{e.diag.message_primary or e}{hint}") from None


def readout(choices: list[Choice]) -> dict[str, Any]:
    """The panel's live figures over the last RECENT selections (the start, chosen without a seam, aside)."""
    recent = [c for c in choices[-RECENT:] if c.latency_ms is not None]
    latency = np.array([c.latency_ms for c in recent])
    seams = np.array([c.continuity for c in recent if c.continuity is not None])
    last = choices[-1]
    return {
        "selections": len(recent),
        "latency_p50_ms": float(np.percentile(latency, 50)) if len(latency) else None,
        "latency_p99_ms": float(np.percentile(latency, 99)) if len(latency) else None,
        "candidates": last.candidates,
        "relax_level": last.relax_level,
        "relaxed_share": float(np.mean([c.relax_level > 0 for c in recent])) if recent else None,
        "seam_ratio_median": float(np.median(seams)) if len(seams) else None,
        "seam_ratio_max": float(seams.max()) if len(seams) else None,
        "seam_rough_share": float(np.mean(seams > 1.0))
        if len(seams)
        else None,  # r > 1: past the thresholds
    }


def choice_message(
    choice: Choice, course: tuple[list, int, bool], choices: list[Choice]
) -> dict[str, Any]:
    return {
        "type": "choice",
        "step": choice.step,
        "snippet_id": choice.snippet_id,
        "clip_id": choice.clip_id,
        "mirrored": choice.mirrored,
        "fps": choice.fps,
        "start_frame": choice.start_frame,
        "end_frame": choice.end_frame,
        "target": choice.target,
        "reached": choice.reached,
        "relax_level": choice.relax_level,
        "continuity": choice.continuity,
        "latency_ms": choice.latency_ms,
        "waited_ms": choice.waited_ms,
        "candidates": choice.candidates,
        "end": {"position": choice.end.position, "heading": choice.end.heading},
        "goals": course[0],
        "goal_index": course[1],
        "readout": readout(choices),
    }


def frame_message(frame: Frame) -> dict[str, Any]:
    return {
        "type": "frame",
        "index": frame.index,
        "step": frame.step,
        "rotations": np.round(frame.rotations, 6).tolist(),
        "translations": np.round(frame.translations, 5).tolist(),
    }


class AvatarSession:
    """The avatar of one browser connection. handle() takes the page's messages; a thread plays the frames."""

    def __init__(self, conninfo: str, send: Send, check: Check, settings: Settings) -> None:
        self._conninfo = conninfo
        self._send = send
        self._check = check
        self.settings = replace(settings, count_candidates=True)
        self._avatar: Avatar | None = None
        self._thread: threading.Thread | None = None
        self._stopping = threading.Event()
        self._placement = Placement((0.0, 0.0, 0.0), 0.0)  # where the next avatar starts
        self._skeleton_sent: int | None = None
        self._skeleton_of: dict[
            tuple[int, int], tuple[int, dict, str]
        ] = {}  # (clip, version) -> skeleton

    def handle(self, message: dict[str, Any]) -> None:
        kind = message.get("type") if isinstance(message, dict) else None
        if kind == "goal":
            self._goal(message)
        elif kind == "settings":
            try:
                settings = settings_from(message, self.settings)
                self._check(settings)
            except SettingsRefused as e:
                self._send(
                    {"type": "refused", "message": str(e), "settings": self.public_settings()}
                )
                return
            self.settings = settings
            if self._avatar is not None:
                self._avatar.settings = settings  # from the next query on
            self._send({"type": "settings", "settings": self.public_settings()})
        else:
            self._send(
                {
                    "type": "refused",
                    "message": f"unknown message type {kind!r}: send goal or settings",
                }
            )

    def public_settings(self) -> dict[str, Any]:
        out = asdict(self.settings)
        out.pop("count_candidates")
        return out

    def _goal(self, message: dict[str, Any]) -> None:
        try:
            goal = checked_goal((message["x"], message["z"]))
        except (KeyError, TypeError, ValueError):
            self._send(
                {
                    "type": "refused",
                    "message": f'a goal is {{"x": metres, "z": metres}}, got {message!r}',
                }
            )
            return
        running = self._thread is not None and self._thread.is_alive()
        if running and message.get("add"):
            self._avatar.add_waypoint(goal)
        elif running:
            self._avatar.set_goal(goal)
        else:  # the first goal, or after the walk stopped on an error: a new avatar where the last one stood
            if self._avatar is not None:
                self._placement = self._avatar.placement
            try:
                self._avatar = self._new_avatar(goal)
            except psycopg.Error as e:
                self._avatar = None
                self._send(
                    {
                        "type": "stopped",
                        "message": f"cannot reach the database: {e}; click to try again",
                    }
                )
                return
            self._thread = threading.Thread(
                target=self._play, args=(self._avatar,), daemon=True, name="modb-avatar-play"
            )
            self._thread.start()
        goals, index, _ = self._avatar.course
        self._send({"type": "goals", "goals": goals, "goal_index": index})

    def _new_avatar(self, goal: tuple[float, ...]) -> Avatar:
        """An avatar on a read-only database session of its own, where the last one stood."""
        conn = connect(self._conninfo)
        try:
            conn.execute(
                "SELECT set_config('default_transaction_read_only', 'on', false), "
                "set_config('statement_timeout', %s, false)",
                [STATEMENT_TIMEOUT],
            )
            return Avatar(
                conn,
                goals=[goal],
                position=self._placement.position,
                heading=self._placement.heading,
                settings=self.settings,
            )
        except BaseException:
            conn.close()
            raise

    def _play(self, avatar: Avatar) -> None:
        """Frames at the source rate; a readout after every selection."""
        due = time.monotonic()
        reported = 0  # choices sent so far
        try:
            for frame in avatar.frames():
                if self._stopping.is_set():
                    break
                choice = avatar.choices[-1]
                if len(avatar.choices) > reported:  # the first frame of a new snippet
                    reported = len(avatar.choices)
                    self._skeleton(avatar, choice)
                    self._send(choice_message(choice, avatar.course, avatar.choices))
                due = max(due, time.monotonic())  # after a stall, on from now: no burst to catch up
                if self._stopping.wait(max(0.0, due - time.monotonic())):
                    break
                self._send(frame_message(frame))
                due += 1.0 / choice.fps
        except NoContinuation as e:
            self._send({"type": "stopped", "message": f"{e}; click to start again"})
        except psycopg.Error as e:
            log.exception("avatar query failed")
            self._send(
                {
                    "type": "stopped",
                    "message": f"the database refused the query: {e.diag.message_primary or e}",
                }
            )
        except Exception as e:  # the page closed (a send failed), or a bug: the server's log has it
            if not self._stopping.is_set():
                log.exception("avatar stopped")
                try:
                    self._send(
                        {"type": "stopped", "message": f"the avatar stopped: {type(e).__name__}"}
                    )
                except Exception:
                    pass
        finally:
            avatar.conn.close()

    def _skeleton(self, avatar: Avatar, choice: Choice) -> None:
        """The skeleton the page poses, when it changes (sent once per avatar for one-skeleton data)."""
        key = (choice.clip_id, choice.version)
        if key not in self._skeleton_of:
            self._skeleton_of[key] = avatar.conn.execute(
                "SELECT s.id, s.hierarchy, s.joint_map->>'pelvis' FROM modb.clip_versions v JOIN modb.skeletons s "
                "ON s.id = v.skeleton_id WHERE v.clip_id = %s AND v.version = %s",
                list(key),
            ).fetchone()
        skeleton_id, hierarchy, pelvis = self._skeleton_of[key]
        if skeleton_id != self._skeleton_sent:
            self._send(
                {"type": "skeleton", "id": skeleton_id, "hierarchy": hierarchy, "pelvis": pelvis}
            )
            self._skeleton_sent = skeleton_id

    def close(self) -> None:
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=30)
