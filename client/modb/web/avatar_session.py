"""Avatar mode: one browser connection drives one Avatar on a database session of its own.

The page sends goals and settings (JSON over the WebSocket); the session plays the Avatar's frames
at the source rate and sends each one, with a readout after every selection. Settings are SET on
this session's own connection (never a shared one), so two pages tune independently. Settings are
checked on another connection first: a bad value is refused with a message and the walk goes on
with the previous ones.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, replace
from typing import Any

import psycopg

from modb.database.read_nodes import NoNode, Node, ReadNodes
from modb.provenance import Origin, Version, as_meta, origins, sources_among
from modb.synthesis.avatar import Avatar, Choice, Frame, NoContinuation, Settings
from modb.synthesis.chain import checked_json_goal
from modb.synthesis.placement import Placement
from modb.synthesis.root_motion import with_root_motion
from modb.synthesis.synth import strip_motion

from .avatar_messages import choice_message, file_message, frame_message, sending_time
from .avatar_settings import SettingsRefused, settings_from
from .downloads import FORMATS

log = logging.getLogger("modb.web")

STATEMENT_TIMEOUT = "10s"  # an avatar's query that takes longer stops it (and frees its slot)
KEEP_SECONDS = 300  # a download holds the last 5 min of the walk (frames: ~10 MB at 30 fps)

Send = Callable[[dict[str, Any]], None]
Check = Callable[[Settings], None]

SKELETON = (
    "SELECT s.id, s.hierarchy, s.joint_map->>'pelvis' FROM modb.clip_versions v "
    "JOIN modb.skeletons s ON s.id = v.skeleton_id WHERE v.clip_id = %s AND v.version = %s"
)


class AvatarSession:
    """A browser connection's avatar: handle() takes the page's messages; a thread plays frames."""

    def __init__(self, nodes: ReadNodes, send: Send, check: Check, settings: Settings) -> None:
        self._nodes = nodes
        self._node: Node | None = None  # where the avatar's queries run now
        self._send = send
        self._check = check
        self.settings = replace(settings, count_candidates=True)
        self._avatar: Avatar | None = None
        self._thread: threading.Thread | None = None
        self._stopping = threading.Event()
        self._placement = Placement((0.0, 0.0, 0.0), 0.0)  # where the next avatar starts
        self._skeleton_sent: int | None = None
        # (clip, version) -> skeleton
        self._skeleton_of: dict[tuple[int, int], tuple[int, dict, str]] = {}
        self._origin_of: dict[Version, Origin | None] = {}  # clip version -> where captured
        # The walk's frames, for downloads: the last KEEP_SECONDS of it (a deque drops the oldest).
        self._walk: deque[Frame] = deque()

    def handle(self, message: dict[str, Any]) -> None:
        kind = message.get("type") if isinstance(message, dict) else None
        if kind == "goal":
            self._goal(message)
        elif kind == "download":
            self._download(message)
        elif kind == "action":
            self._send({"type": "refused", "message": "actions need a graph of models (they are "
                        "its action nodes): choose one under *walks by*"})  # fmt: skip
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
                    "message": f"unknown message type {kind!r:.200}: send goal, settings or "
                    "download",
                }
            )

    def public_settings(self) -> dict[str, Any]:
        out = asdict(self.settings)
        out.pop("count_candidates")
        return out

    def _goal(self, message: dict[str, Any]) -> None:
        try:
            goal = checked_json_goal((message["x"], message["z"]))
        except (KeyError, TypeError, ValueError, OverflowError):  # OverflowError: a huge integer
            self._send(
                {
                    "type": "refused",
                    "message": f'a goal is {{"x": metres, "z": metres}}, got {message!r:.200}',
                }
            )
            return
        running = self._thread is not None and self._thread.is_alive()
        if running and message.get("add"):
            self._avatar.add_waypoint(goal)
        elif running:
            self._avatar.set_goal(goal)
        else:  # first goal, or the walk stopped on an error: a new avatar where the last one stood
            if self._avatar is not None:
                self._placement = self._avatar.placement
            try:
                self._avatar = self._new_avatar(goal)
            except (psycopg.Error, NoNode) as e:
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
        """An avatar on a read-only database session of its own (on a standby when there are
        some), where the last one stood."""
        conn = self._open()
        try:
            return Avatar(
                conn,
                goals=[goal],
                position=self._placement.position,
                heading=self._placement.heading,
                settings=self.settings,
                failover=self._failover,
            )
        except BaseException:
            conn.close()
            self._release()
            raise

    def _open(
        self, needed_snippet: int | None = None, avoid: tuple[str, ...] = ()
    ) -> psycopg.Connection:
        self._node, conn = self._nodes.open(needed_snippet, avoid)
        try:
            conn.execute(
                "SELECT set_config('default_transaction_read_only', 'on', false), "
                "set_config('statement_timeout', %s, false)",
                [STATEMENT_TIMEOUT],
            )
        except BaseException:
            conn.close()
            self._release()
            raise
        return conn

    def _release(self) -> None:
        if self._node is not None:
            self._nodes.release(self._node)
            self._node = None

    def _failover(self, needed_snippet: int | None) -> psycopg.Connection:
        """The avatar's node stopped: another that has the snippet the walk continues from."""
        gone = self._node
        self._release()
        if gone is not None:
            self._nodes.mark_down(gone)
        conn = self._open(needed_snippet, avoid=(gone.name,) if gone else ())
        where = gone.name if gone else "its node"
        try:
            self._send(
                {"type": "note", "message": f"{where} stopped answering: on to {self.node_name}"}
            )
        except BaseException:  # the page is gone: the avatar never gets the connection
            conn.close()
            raise
        return conn

    def _play(self, avatar: Avatar) -> None:
        """Frames at the source rate; a readout after every selection."""
        due = time.monotonic()
        reported = 0  # choices sent so far
        notes_sent = 0
        self._walk.clear()
        try:
            for frame in avatar.frames():
                if self._stopping.is_set():
                    break
                choice = avatar.choices[-1]
                if len(avatar.choices) > reported:  # the first frame of a new snippet
                    reported = len(avatar.choices)
                    self._skeleton(avatar, choice)
                    if notes_sent < len(avatar.notes):  # what the database chose, and why
                        self._send({"type": "note", "message": "; ".join(avatar.notes)})
                        notes_sent = len(avatar.notes)
                    self._send(
                        choice_message(
                            choice,
                            avatar.course,
                            avatar.choices,
                            self.node_name,
                            self._origin(avatar, (choice.clip_id, choice.version)),
                        )
                    )
                self._keep(frame, choice.fps)
                due = sending_time(due, time.monotonic())
                if self._stopping.wait(max(0.0, due - time.monotonic())):
                    break
                self._send(frame_message(frame))
                due += 1.0 / choice.fps
        except (NoContinuation, NoNode) as e:
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
            self._release()

    @property
    def node_name(self) -> str | None:
        node = self._node
        return None if node is None else node.name

    def _origin(self, avatar: Avatar, version: Version) -> Origin | None:
        """The source the chosen snippet's clip version came from (read once); None when the
        lookup fails: the readout shows none, the avatar walks on."""
        if version not in self._origin_of:
            self._origin_of[version] = None  # asked once, whatever the answer
            try:
                self._origin_of.update(origins(avatar.conn, [version]))
            except psycopg.Error:
                log.warning(
                    "the source of clip version %s could not be read", version, exc_info=True
                )
        return self._origin_of[version]

    def _skeleton(self, avatar: Avatar, choice: Choice) -> None:
        """The skeleton the page poses, when it changes: once per avatar for one-skeleton data."""
        key = (choice.clip_id, choice.version)
        if key not in self._skeleton_of:
            try:
                self._skeleton_of[key] = avatar.conn.execute(SKELETON, key).fetchone()
            except psycopg.OperationalError as e:
                if avatar.conn.broken:  # its node stopped since the choice: on to another
                    avatar.use_connection(self._failover(choice.snippet_id))
                elif not isinstance(e, psycopg.errors.SerializationFailure):  # a replay conflict
                    raise
                self._skeleton_of[key] = avatar.conn.execute(SKELETON, key).fetchone()
        skeleton_id, hierarchy, pelvis = self._skeleton_of[key]
        if skeleton_id != self._skeleton_sent:
            self._send(
                {"type": "skeleton", "id": skeleton_id, "hierarchy": hierarchy, "pelvis": pelvis}
            )
            self._skeleton_sent = skeleton_id

    def _keep(self, frame: Frame, fps: float) -> None:
        self._walk.append(frame)
        while len(self._walk) > KEEP_SECONDS * fps:
            self._walk.popleft()

    def _download(self, message: dict[str, Any]) -> None:
        """The walk so far (its last KEEP_SECONDS), with root motion, as a file the page saves."""
        fmt = message.get("format")
        avatar, frames = self._avatar, list(self._walk)
        if fmt not in FORMATS or avatar is None or not frames:
            why = (
                f"format is one of {', '.join(FORMATS)}, got {fmt!r:.50}"
                if fmt not in FORMATS
                else "nothing walked yet: click the ground first"
            )
            self._send({"type": "refused", "message": f"no download: {why}"})
            return
        first = avatar.choices[0]
        template = avatar.library.get(first.clip_id, first.version, first.mirrored).motion
        walk = with_root_motion(strip_motion(frames, template, "walk"))
        self._send(file_message(walk, fmt, self._sources(avatar, frames)))

    def _sources(self, avatar: Avatar, frames: list[Frame]) -> list[dict]:
        """The sources of the kept walk's snippets and their terms, from the origins the readout
        already looked up for each choice (no query: the walk keeps the connection busy)."""
        by_step = {c.step: (c.clip_id, c.version) for c in avatar.choices}
        versions = [by_step[s] for s in dict.fromkeys(f.step for f in frames) if s in by_step]
        return as_meta(sources_among(self._origin_of, versions))

    def close(self) -> None:
        self._stopping.set()
        if self._thread is not None:
            self._thread.join(timeout=30)
