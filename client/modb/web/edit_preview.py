"""POST /api/clips/ID/edit-preview: an edit script's result on a clip's current version, computed
and not stored (the web view's pose editor previews each drag with it). The kernel runs here, in
the server's process, on the clip as the database holds it (edit_clips.current_clip) with
edits.apply_with_notes: the code `modb edit apply` and POST /api/edit-scripts/NAME/apply run, so
what the page previews is what saving stores (within float4's rounding). A read: a reader may ask
(a token only with --require-token); nothing is written.

It takes the pose editor's commands, ik and rotate, at most MAX_COMMANDS (each costs a solve over
its blend range: the work and the answer stay bounded; other scripts are applied, not previewed).
The answer: the frames that differ from the version's, start..start+count-1 (the frames the blend
ranges cover), as
/api/clips/ID/frames gives them (local rotations, translations, world positions), and each
command's note (edits.apply_with_notes: for ik the target, the point reached, its distance, and a
message when the target is out of reach)."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np
import psycopg
from psycopg_pool import ConnectionPool
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import JSONResponse

from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import edit_clips, kinematics, pose_edits
from modb_kernel import edits as E

from .api import BadRequest, NotFound
from .auth import Tokens
from .bodies import json_body, parse
from .body_models import EDIT_SCRIPT, Body

MAX_BODY_BYTES = 1 << 20  # a script of a few thousand commands
MAX_COMMANDS = 100  # a pose edited by hand: far more drags than anyone makes in one go
CACHED_VERSIONS = 8  # clip versions kept read: a drag previews one version many times


# The clip's newest version and, as its cache key, the row versions of that version and of its
# skeleton (xmin and ctid, as modb_kernel.prepared_models keys models): a version deleted and its
# number used again, or a skeleton's joint map edited, is another key.
CURRENT = """SELECT v.version, concat_ws(' ', v.xmin, v.ctid, s.id, s.xmin, s.ctid)
               FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
              WHERE v.clip_id = %s ORDER BY v.version DESC LIMIT 1"""


def _current(conn: psycopg.Connection, clip_id: int) -> tuple[int, str] | None:
    """(version, row key) of the clip's newest version, None where it has none."""
    return conn.execute(CURRENT, [clip_id]).fetchone()


class _VersionCache:
    """Clip versions as edit_clips.current_clip reads them, by their rows (CURRENT): a drag's
    updates read the version once. Its arrays, the skeleton's too, are made read-only: a command
    that changed its input in place would fail rather than spoil the next preview."""

    def __init__(self, size: int):
        self.size, self._clips, self._lock = size, OrderedDict(), threading.Lock()

    def get(self, conn: psycopg.Connection, clip_id: int, current: tuple[int, str]) -> dict | None:
        key = (clip_id, current[1])
        with self._lock:
            if key in self._clips:
                self._clips.move_to_end(key)
                return self._clips[key]
        clip = edit_clips.current_clip(WorkerDatabase(conn), clip_id)
        if clip is None or _current(conn, clip_id) != current:  # a newer one came meanwhile
            return clip
        for value in (*clip.values(), *clip["skeleton"].values()):
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
        with self._lock:
            self._clips[key] = clip
            while len(self._clips) > self.size:
                self._clips.popitem(last=False)
        return clip


_versions = _VersionCache(CACHED_VERSIONS)


class EditPreview(Body):
    """An edit script to preview on a clip's current version (nothing is stored)."""

    commands: EDIT_SCRIPT


def _window(notes: list) -> tuple[int, int]:
    """(first, last) frame that may differ from the version's: the commands' blend ranges."""
    spans = [n["frames"] for n in notes if n is not None]
    return min(s[0] for s in spans), max(s[1] for s in spans)


def preview(conn: psycopg.Connection, clip_id: int, commands: list[dict[str, Any]]) -> dict:
    """The script's result on the clip's current version: the frames it changes and the notes."""
    others = sorted({c.get("op") for c in commands} - set(pose_edits.EDITS))
    if others:
        raise BadRequest(f"a preview takes the pose editor's commands, ik and rotate: "
                         f"{others[0]!r} is applied, not previewed (modb edit apply, POST "
                         "/api/edit-scripts/NAME/apply)")  # fmt: skip
    if len(commands) > MAX_COMMANDS:
        raise BadRequest(f"a preview takes at most {MAX_COMMANDS} commands, got {len(commands)}: "
                         "save the edits so far, then go on")
    current = _current(conn, clip_id)
    if current is None:
        raise NotFound(f"no clip with id {clip_id} (with a version of its own)")
    version = current[0]
    clip = _versions.get(conn, clip_id, current)
    if clip is None:
        raise NotFound(f"no clip with id {clip_id}")
    sk = clip["skeleton"]
    try:  # ik and rotate keep the clip's frames: no result larger than the version
        edited, notes = E.apply_with_notes(clip, commands)
    except E.EditError as e:
        raise BadRequest(str(e)) from None
    rotations, translations = edited["rotations"], edited["translations"]
    first, last = _window(notes)
    part = slice(first, last + 1)
    positions = kinematics.world_positions(sk["parents"], sk["offsets"], rotations[part],
                                           translations[part], sk["translated"])  # fmt: skip
    return {
        "clip_id": clip_id,
        "version": version,
        "fps": edited["fps"],
        "n_frames": int(rotations.shape[0]),
        "start": first,
        "count": last - first + 1,
        "rotations": np.round(rotations[part], 7).tolist(),
        "translations": np.round(translations[part], 6).tolist(),
        "positions": np.round(positions, 6).tolist(),
        "notes": notes,
    }


def endpoint(pool: ConnectionPool, tokens: Tokens, gate: Any, clip_id: Callable) -> Callable:
    """The route's endpoint: the token (with --require-token), the body checked, then a turn at
    the gate, a thread and a pooled connection."""

    def answer(ident: int, commands: list[dict[str, Any]]) -> JSONResponse:
        with pool.connection() as conn:
            return JSONResponse(preview(conn, ident, commands))

    async def run(request: Request) -> JSONResponse:
        await run_in_threadpool(tokens.reader, request)  # before the body is read
        ident = clip_id(request)
        commands = parse(EditPreview, await json_body(request, MAX_BODY_BYTES))["commands"]
        async with gate.turn():
            return await run_in_threadpool(answer, ident, commands)

    run.request_body = EditPreview
    return run
