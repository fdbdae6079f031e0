"""The Avatar: a character walking toward goals by chaining snippets select_next_snippet chooses.

It keeps its world placement (pelvis ground point and heading), asks the database for the next
snippet with the goal in world coordinates, places that snippet where the previous one ended and
yields its frames at the source rate. The next selection is issued `lead_time` seconds before the
current snippet ends (the paper's latency hiding): the query runs while the last frames play, and
a goal set or added after it started asks again, from the same snippet, with the new course (the
first answer is dropped); a new goal while a snippet plays chooses it again from the one before and
fades into it, and the snippet first serving a new goal is steered toward it (steer.py). Rules
(goals, arrival, exclusion) are those of modb.synthesize, so with lead time zero and no goal
changed both give the same chain. Seams are treated as settings.seam says, then each
snippet's stance feet are held (modb_kernel.foot_hold, unless settings.foot_hold is False) before
its frames are yielded.
"""

from __future__ import annotations

import contextlib
import copy
import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
import psycopg


from modb.database.connection import configure_for_selection
from modb.validation import checked_number

from .blend import CROSS_FADE_SECONDS, blend_seam, cross_fade
from .inertialize import Seams
from .feet import FootHold, feet_held
from .chain import (
    MAX_ID,
    Choice,
    Frame,
    Goal,
    NoContinuation,
    Settings,
    checked_goal,
    checked_heading,
    checked_position,
)
from .defaults import describe_pool, largest_pool, session_graph
from .placement import Placement, after, ground_distance, place_root
from .source_frames import FrameLibrary
from .steer import steer


_ARGUMENTS = """%(prev)s::bigint, %(position)s::float8[], %(heading)s::float8, %(target)s::float8[],
    %(profile)s, %(collection)s, %(exclude)s::bigint[]"""


def _chosen(selection: str) -> str:
    """The query reading the row of the snippet that `selection` (a call of a selection function)
    chooses."""
    return f"""
SELECT n.snippet_id, n.clip_id, n.version, n.mirrored, n.first_frame, n.n_frames, n.relax_level,
       n.continuity, n.proximity, n.net_translation, n.net_heading, s.fps, b.heading
  FROM {selection} n
  JOIN modb.snippets s ON s.id = n.snippet_id
  JOIN modb.terminators b ON b.id = s.begin_terminator
"""


_SELECT = _chosen(f"modb.select_next_snippet_world({_ARGUMENTS})")
# Every step after the first (89_synthesis.sql): coming to rest after the last goal, setting
# off from standing, else select_next_snippet_world, as modb.synthesize steps.
_STEP = _chosen(f"modb.select_synthesis_step({_ARGUMENTS}, %(resting)s)")
_START = """
SELECT s.id, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames, NULL::int, NULL::float8,
       NULL::float8, s.net_translation, s.net_heading, s.fps, b.heading
  FROM modb.snippets s JOIN modb.terminators b ON b.id = s.begin_terminator
 WHERE s.id = %s
"""


# The snippet of a clip's newest version nearest a dropped one (same side, same rate).
_STAND_IN = """
SELECT s.id
  FROM modb.snippets s JOIN modb.current_clips c ON c.clip_id = s.clip_id AND c.version = s.version
 WHERE s.clip_id = %(clip_id)s AND s.mirrored = %(mirrored)s AND s.fps = %(fps)s
 ORDER BY abs(s.first_frame - %(first_frame)s), s.id
 LIMIT 1
"""


ASK_AGAIN = 3  # a choice cancelled by a standby's replay, or whose node stopped, is asked again
# A new goal while a snippet plays: it is chosen again toward it, from the snippet before, and faded
# into from this long after the frame playing (time for the query) over CROSS_FADE_SECONDS.
REPLACE_LEAD_SECONDS = 0.15


@dataclass
class Avatar:
    conn: psycopg.Connection
    goals: Sequence[Goal] = ()
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    heading: float = 0.0
    start_snippet: int | None = None
    settings: Settings = field(default_factory=Settings)
    # When the connection breaks (its node stopped): another, to a node that has the snippet id
    # given (the one the chain continues from); None: the walk stops with the error.
    failover: Callable[[int | None], psycopg.Connection] | None = None

    def __post_init__(self) -> None:
        # Refused before the connection is used.
        self.position = checked_position(self.position)
        self.heading = checked_heading(self.heading)
        if self.start_snippet is not None:
            self.start_snippet = checked_number(
                "start_snippet", self.start_snippet, 1, MAX_ID, whole=True
            )
        self._lock = threading.Lock()
        self._goals: list[Goal] = [checked_goal(g) for g in self.goals]
        self._goal_index = 0
        # the current goal was reached (the queue moves on when one is added)
        self._goal_reached = False
        self._course_changes = 0  # goals set or added so far: a query knows which it saw
        self._recent: list[tuple[int, int]] = []  # (snippet id, strip frame where its play ended)
        self._started = False
        self.library = FrameLibrary(self.conn)
        self.choices: list[Choice] = []
        # What this avatar last SET modb.<knob> to on its connection.
        self._knobs_set: dict[str, str] = {}
        configure_for_selection(self.conn)
        # What the database chose where the settings say nothing (as modb.synthesize does), and
        # why, for the caller to show: the collection of the largest pool, the graph per scope.
        self.notes: list[str] = []
        self._default_collection: str | None = None
        if self.settings.collection is None and self.start_snippet is None:
            pool = largest_pool(self.conn)
            if pool is not None:
                self._default_collection = pool.collection
                if pool.pools > 1:
                    self.notes.append(describe_pool(pool))
        self._graphs: dict[tuple[str | None, str, str | None], str] = {}
        self._rest_data: dict[str | None, bool] = {}  # collection: has motion that ends standing

    # Goals may change at any time (from another thread too): they apply to the next query issued,
    # and a query issued for the next snippet before they came is issued again (frames()).
    def set_goal(self, goal: Goal) -> None:
        with self._lock:
            self._goals, self._goal_index, self._goal_reached = [checked_goal(goal)], 0, False
            self._course_changes += 1

    def add_waypoint(self, goal: Goal) -> None:
        with self._lock:
            self._goals.append(checked_goal(goal))
            self._course_changes += 1

    @property
    def goal(self) -> Goal | None:
        with self._lock:
            return self._goals[self._goal_index] if self._goals else None

    @property
    def course(self) -> tuple[list[Goal], int, bool]:
        """The goal queue, the index of the goal being served, and whether it was reached."""
        with self._lock:
            return list(self._goals), self._goal_index, self._goal_reached

    @property
    def placement(self) -> Placement:
        """The avatar's placement (pelvis ground point, heading) after the last chosen snippet."""
        if self.choices:
            return self.choices[-1].end
        return Placement(tuple(float(v) for v in self.position), float(self.heading))

    def frames(self) -> Iterator[Frame]:
        """Frames of the growing strip, forever (stop consuming to stop); an Avatar plays one strip.

        The first snippet plays whole, every later one without its first frame (it stands in for the
        previous snippet's last). Raises NoContinuation when the database finds no next snippet.
        """
        if self._started:
            raise RuntimeError(
                "an Avatar plays one strip: make a new Avatar (at avatar.placement) to start again"
            )
        self._started = True
        executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="modb-avatar")
        try:
            seen = self._course_changes
            asked: tuple[Choice | None, dict] = (None, self._request(None))
            pending: Future | None = executor.submit(self._choose, *asked)
            played: list[Frame] = []  # the last two frames played: a seam's left side
            joints = _Joins(self)
            while True:
                started = time.perf_counter()
                choice, rotations, translations, as_placed = self._answer(pending, asked)
                waited = (time.perf_counter() - started) * 1000.0
                choice = replace(choice, waited_ms=waited if self.choices else 0.0)
                self.choices.append(choice)
                previous, played_before = asked[0], list(played)
                rotations, translations, shown = joints.join(
                    choice, rotations, translations, as_placed, played
                )
                skip = 0 if choice.step == 0 else 1
                lead_frames = int(round(self.settings.lead_time * choice.fps))
                replace_lead = int(round(REPLACE_LEAD_SECONDS * choice.fps))
                fade = int(round(CROSS_FADE_SECONDS * choice.fps))
                pending = replacing = None
                k = skip
                while k < choice.n_frames:
                    frame = Frame(choice.start_frame + k, choice.step, shown[k], translations[k])
                    yield frame
                    # the next seam joins the strip before its feet were held: the hold is
                    # continuous on its own, and its changes are not a seam's to carry
                    played = [*played[-1:], replace(frame, rotations=rotations[k])]
                    k += 1
                    if replacing is not None and k >= replacing[1]:
                        # the snippet playing, chosen again toward the new goal, faded into; a
                        # query not answered by now is dropped (the next snippet takes the goal)
                        if not replacing[0].done():
                            replacing[0].cancel()
                            replacing = None
                            continue
                        new, r, t, placed = self._answer(replacing[0], replacing[2])
                        if new.fps == choice.fps and k + fade + 2 <= min(new.n_frames,
                                                                         choice.n_frames):
                            r, t, s = joints.join_again(new, r, t, placed, played_before)
                            shown, translations = cross_fade((shown, translations), (s, t), k, fade)
                            rotations, choice = r, new
                            self.choices.append(choice)
                        replacing = None
                    changed = self._course_changes != seen
                    if changed and previous is not None and replacing is None and (
                            choice.n_frames - k >= replace_lead + fade + 2):  # fmt: skip
                        # a new goal while enough of the snippet is left: it is chosen again
                        # from the one before it, the new goal in view
                        if pending is not None:
                            pending.cancel()  # a query not started yet is not run for nothing
                        seen, pending = self._course_changes, None
                        again = (previous, {**self._request(previous),
                                            "steer_from": k + replace_lead})  # fmt: skip
                        replacing = (executor.submit(self._choose, *again), k + replace_lead, again)
                        continue
                    due = replacing is None and pending is None
                    due = due and choice.n_frames - k <= lead_frames
                    # a goal came after the next snippet was asked for: asked again with it, so
                    # the walk answers from the snippet playing (the first answer is dropped)
                    if due or (pending is not None and changed):
                        if pending is not None:
                            pending.cancel()
                        request = self._request(choice)
                        if changed:  # the next snippet is the first to serve the new goal
                            request["steer_from"] = 1
                        seen = self._course_changes
                        asked = (choice, request)
                        pending = executor.submit(self._choose, *asked)
        finally:
            executor.shutdown(wait=True, cancel_futures=True)

    def _answer(
        self, pending: Future, asked: tuple[Choice | None, dict]
    ) -> tuple[Choice, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The pending choice. On a hot standby a query may be cancelled by what the standby
        replays, and a node may stop: the same question is asked again (up to ASK_AGAIN times), on
        this connection after a conflict, else on the connection `failover` gives (a node that has
        the snippet the chain continues from)."""
        try:
            return pending.result()
        except psycopg.Error as e:
            error = e
        for _ in range(ASK_AGAIN):
            if self.conn.broken and self.failover is not None:
                self.use_connection(self.failover(asked[1]["prev"]))
            elif self.conn.broken or not isinstance(error, psycopg.errors.SerializationFailure):
                raise error  # "conflict with recovery" is asked again; anything else ends the walk
            try:
                return self._choose(*asked)
            except psycopg.Error as e:
                error = e
        raise error

    def use_connection(self, conn: psycopg.Connection) -> None:
        """Go on on another database session: the same chain, goals and exclusions; the session's
        settings are made again there."""
        old, self.conn = self.conn, conn
        self.library.conn = conn
        self._knobs_set = {}
        with contextlib.suppress(psycopg.Error):
            old.close()
        configure_for_selection(conn)

    def _request(self, previous: Choice | None) -> dict:
        """The next query's arguments, fixed now (later goals ask again: frames())."""
        with self._lock:
            if not self._goals:
                raise ValueError("the avatar has no goal: call set_goal((x, z)) first")
            if (
                previous is not None
                and previous.reached
                and self._goals[self._goal_index] == previous.target
            ):
                self._goal_reached = True
            if self._goal_reached and self._goal_index < len(self._goals) - 1:
                self._goal_index, self._goal_reached = self._goal_index + 1, False
            goal_index, target = self._goal_index, self._goals[self._goal_index]
            # the last goal reached: come to rest (modb.synthesize's rule)
            resting = self._goal_reached and goal_index == len(self._goals) - 1
        s, collection = self.settings, self.collection
        if previous is None:
            where = self.placement
            exclude = None
        else:
            where = previous.end
            window = s.exclude_seconds * previous.fps
            played = (previous.snippet_id, previous.end_frame)
            # a snippet asked for again after a new goal is in the window once
            recent = self._recent if played in self._recent else [*self._recent, played]
            self._recent = [(i, e) for i, e in recent if previous.end_frame - e < window]
            exclude = [i for i, _ in self._recent]
        return {
            "prev": None if previous is None else previous.snippet_id,
            "position": list(where.position),
            "heading": where.heading,
            "target": list(target),
            "profile": s.profile,
            "collection": collection,
            "knobs": {**s.knobs, "graph": self._graph(s.graph, s.profile, collection)},
            "exclude": exclude,
            "count_candidates": s.count_candidates,
            "goal": goal_index + 1,
            "where": where,
            "start_frame": 0 if previous is None else previous.end_frame,
            "step": 0 if previous is None else previous.step + 1,
            "arrival_radius": s.arrival_radius,
            "fps": None if previous is None else previous.fps,
            "resting": resting and previous is not None,
        }

    def _choose(
        self, previous: Choice | None, request: dict
    ) -> tuple[Choice, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """In the worker thread: the selection query, then the chosen snippet's placed frames
        (steered toward a new goal when the request says from which frame) and the frames as
        placed before steering."""
        t = time.perf_counter()
        candidates = None
        if previous is None and self.start_snippet is not None:
            row, latency = self.conn.execute(_START, [self.start_snippet]).fetchone(), None
            if row is None:
                raise NoContinuation(
                    f"no snippet {self.start_snippet} (start_snippet is a modb.snippets id)"
                )
        else:
            self._set_knobs(request["knobs"])
            query = {
                k: request[k]
                for k in (
                    "prev",
                    "position",
                    "heading",
                    "target",
                    "profile",
                    "collection",
                    "exclude",
                )
            }
            if request["prev"] is None:
                row = self.conn.execute(_SELECT, query, prepare=True).fetchone()
                latency = (time.perf_counter() - t) * 1000.0
                # Asked now, before the first frames play, not when the walk comes to rest
                # (a small collection of a large database: a quarter of a second).
                self._can_rest(request["collection"])
            else:
                query["resting"] = request["resting"] and self._can_rest(request["collection"])
                row = self._step(query, previous)
                latency = (time.perf_counter() - t) * 1000.0
            if row is not None and request["count_candidates"]:
                candidates = self._candidates(query.get("prev"), row[6], request["profile"])
            if row is None and previous is None:
                raise NoContinuation(
                    "no snippet to start from: the collection (or the database) has no snippets; "
                    "`modb load` builds them"
                )
            if row is None:
                raise NoContinuation(
                    f"no snippet can follow snippet {request['prev']}: every candidate was "
                    f"excluded; "
                    "lower exclude_seconds or load more data"
                )
        (
            snippet_id,
            clip_id,
            version,
            mirrored,
            first_frame,
            n_frames,
            relax_level,
            continuity,
            proximity,
            net_translation,
            net_heading,
            fps,
            source_heading,
        ) = row
        if request["fps"] is not None and fps != request["fps"]:
            raise RuntimeError(
                f"snippet {snippet_id} plays at {fps} fps after a {request['fps']} fps snippet"
            )
        where = request["where"]
        end = after(where, tuple(net_translation), net_heading)
        target = tuple(request["target"])
        source = self.library.get(clip_id, version, mirrored)
        window = slice(first_frame, first_frame + n_frames)
        rotations = source.motion.rotations[window].copy()
        translations = source.motion.translations[window].copy()
        ground = source.pelvis[first_frame] * np.array([1.0, 0.0, 1.0])
        rotations[:, 0], translations[:, source.root_track] = place_root(
            rotations[:, 0], translations[:, source.root_track], ground, source_heading, where
        )
        as_placed, steered = (rotations, translations), 0.0
        if request.get("steer_from") is not None:  # the first snippet to serve a new goal
            rotations, translations, end, steered = steer(
                source.skeleton, rotations, translations, source.root_track, end, target,
                request["steer_from"], fps)  # fmt: skip
        choice = Choice(
            step=request["step"],
            snippet_id=snippet_id,
            clip_id=clip_id,
            version=version,
            mirrored=mirrored,
            first_frame=first_frame,
            n_frames=n_frames,
            fps=fps,
            start_frame=request["start_frame"],
            end_frame=request["start_frame"] + n_frames - 1,
            placement=where,
            end=end,
            goal=request["goal"],
            target=target,
            reached=ground_distance(end.position, target) <= request["arrival_radius"],
            relax_level=relax_level,
            continuity=continuity,
            proximity=proximity,
            latency_ms=latency,
            waited_ms=0.0,
            candidates=candidates,
            steered_degrees=math.degrees(steered),
        )
        return choice, rotations, translations, as_placed

    def _step(self, query: dict, previous: Choice) -> tuple | None:
        """The step after a snippet. An edit of that snippet's clip, committed since it was chosen,
        rebuilds the clip's snippets and drops this one: the walk goes on from the snippet of the
        clip's new version nearest the dropped one (the same frames after a smoothing, say; the
        seam treatment smooths what differs), or stops saying why when the new version has none at
        this rate."""
        try:
            return self.conn.execute(_STEP, query, prepare=True).fetchone()
        except psycopg.errors.InvalidParameterValue:  # check_request: "no snippet N"
            if not self._gone(query["prev"]):
                raise
        where = {k: getattr(previous, k) for k in ("clip_id", "mirrored", "fps", "first_frame")}
        found = self.conn.execute(_STAND_IN, where).fetchone()
        if found is None:
            raise NoContinuation(
                f"snippet {previous.snippet_id} was dropped by an edit of clip {previous.clip_id}, "
                f"whose new version has no snippet at {previous.fps:g} fps; click to start again"
            )
        self.notes.append(
            f"snippet {previous.snippet_id} was rebuilt by an edit of clip {previous.clip_id}: "
            f"going on from snippet {found[0]} of its new version"
        )
        query["prev"] = found[0]  # what the readout counts from too
        return self.conn.execute(_STEP, query, prepare=True).fetchone()

    def _gone(self, snippet: int) -> bool:
        return self.conn.execute(
            "SELECT NOT EXISTS (SELECT FROM modb.snippets WHERE id = %s)", [snippet]
        ).fetchone()[0]

    def _candidates(self, prev: int | None, relax_level: int, profile: str) -> int | None:
        """The readout's count of candidates examined; None when an edit dropped `prev` since."""
        try:
            return self.conn.execute(
                "SELECT modb.candidates_examined(%s, %s, %s)", [prev, relax_level, profile]
            ).fetchone()[0]
        except psycopg.errors.RaiseException:  # "no snippet N"
            if prev is None or not self._gone(prev):
                raise
            return None

    @property
    def collection(self) -> str | None:
        """The collection the next selection draws from."""
        s = self.settings
        return s.collection if s.collection is not None else self._default_collection

    def _graph(self, graph: str | None, profile: str, collection: str | None) -> str:
        """SET modb.graph for the next query: the settings' graph, else the scope's default one
        (looked up once per scope; a note says when there is none)."""
        key = (graph, profile, collection)
        if key not in self._graphs:
            self._graphs[key], note = session_graph(self.conn, graph, profile, collection)
            if note:
                self.notes.append(note)
        return self._graphs[key]

    def _can_rest(self, collection: str | None) -> bool:
        """Whether the data has motion that ends standing (modb.can_rest, once per collection, as
        modb.synthesize asks once); a note says when it has none."""
        if collection not in self._rest_data:
            (can,) = self.conn.execute("SELECT modb.can_rest(%s)", [collection]).fetchone()
            self._rest_data[collection] = can
            if not can:
                self.notes.append(
                    "the data has no motion that stops or stands (no snippet ends slower than "
                    "0.1 m/s): after the last goal the avatar keeps walking about it"
                )
        return self._rest_data[collection]

    def _set_knobs(self, knobs: dict[str, str]) -> None:
        """The session's SET modb.<knob>, as in psql; a knob left out goes back to the profile's."""
        wanted = {**{k: "" for k in self._knobs_set}, **knobs}
        for knob, value in wanted.items():
            if self._knobs_set.get(knob, "") != value:
                self.conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
        self._knobs_set = {k: v for k, v in wanted.items() if v != ""}


class _Joins:
    """How a chosen snippet's frames join the strip: the seam treatment (Settings.seam) after the
    frames played, then its stance feet held (Settings.foot_hold), the hold fed piece by piece."""

    def __init__(self, avatar: Avatar) -> None:
        self.avatar = avatar
        self.seams: Seams | None = None
        self.hold: FootHold | None = None
        self._before: FootHold | None = None  # the hold before the last snippet joined

    def join_again(self, choice: Choice, rotations: np.ndarray, translations: np.ndarray,
                   as_placed: tuple[np.ndarray, np.ndarray],
                   played: list[Frame]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """join() in place of the last snippet joined (chosen again while it plays): the hold
        fed from where it stood before that one."""
        self.hold = self._before
        return self.join(choice, rotations, translations, as_placed, played)

    def join(self, choice: Choice, rotations: np.ndarray, translations: np.ndarray,
             as_placed: tuple[np.ndarray, np.ndarray],
             played: list[Frame]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """(rotations, translations) as joined after `played`, and the rotations shown.
        as_placed: the frames before steering; their feet decide contacts and heights (a
        steered snippet's turn would read as feet moving)."""
        settings, library = self.avatar.settings, self.avatar.library
        # a blend changes the frames in place
        reference = as_placed[0].copy(), as_placed[1].copy()
        if settings.seam == "inertialize" and len(played) == 2:
            if self.seams is None:  # a chain has one skeleton
                source = library.get(choice.clip_id, choice.version, choice.mirrored)
                self.seams = Seams(source.skeleton)
            rotations, translations = self.seams.inertialize_after(
                (played[0], played[1]), rotations, translations, choice.fps
            )
        elif settings.seam == "blend" and played:
            rotations, translations = blend_seam(
                played[-1], rotations, translations, settings.blend_frames
            )
        if not settings.foot_hold:
            return rotations, translations, rotations
        skip = 0 if choice.step == 0 else 1
        if self.hold is None:  # a chain has one skeleton and rate
            skeleton = library.get(choice.clip_id, choice.version, choice.mirrored).skeleton
            self.hold = feet_held(skeleton, choice.fps)
        self._before = copy.deepcopy(self.hold)
        shown = rotations.copy()
        shown[skip:] = self.hold.feed(rotations[skip:], translations[skip:],
                                      (reference[0][skip:], reference[1][skip:]))  # fmt: skip
        return rotations, translations, shown

