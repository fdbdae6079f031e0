"""POST /api/clips/ID/edit-preview: an edit script's result on a clip's current version, computed
and not stored (the web view's pose editor previews each drag with it). The kernel runs here, in
the server's process, on the clip as the database holds it (edit_clips.current_clip) with
edits.apply_with_notes: the code `modb edit apply` and POST /api/edit-scripts/NAME/apply run, so
what the page previews is what saving stores (within float4's rounding). A read: a reader may ask
(a token only with --require-token); nothing is written.

The answer: the frames that differ from the version's, start..start+count-1 (for a script of ik
and rotate commands, the frames their blend ranges cover; for others, every frame), as
/api/clips/ID/frames gives them (local rotations, translations, world positions), and each
command's note (edits.apply_with_notes: for ik the target, the point reached, its distance, and a
message when the target is out of reach)."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import psycopg
from psycopg_pool import ConnectionPool
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse

from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import edit_clips, kinematics, pose_edits
from modb_kernel import edits as E

from .api import BadRequest, NotFound
from .auth import Tokens
from .bodies import parse
from .body_models import EDIT_SCRIPT, Body

MAX_BODY_BYTES = 1 << 20  # a script of a few thousand commands


class EditPreview(Body):
    """An edit script to preview on a clip's current version (nothing is stored)."""

    commands: EDIT_SCRIPT


def _body(raw: bytes) -> Any:
    try:
        return json.loads(raw)
    except RecursionError:
        raise HTTPException(400, "the body is nested too deep") from None
    except (ValueError, UnicodeDecodeError) as e:
        raise HTTPException(400, f"the body is not JSON: {e}") from None


async def _read(request: Request) -> bytes:
    length = request.headers.get("content-length")
    if length is None or not length.isdigit():
        raise HTTPException(411, "send Content-Length")
    if int(length) > MAX_BODY_BYTES:
        raise HTTPException(413, f"the body is larger than {MAX_BODY_BYTES:,} bytes")
    raw = bytearray()
    async for chunk in request.stream():
        raw += chunk
        if len(raw) > MAX_BODY_BYTES:
            raise HTTPException(413, f"the body is larger than {MAX_BODY_BYTES:,} bytes")
    return bytes(raw)


def _window(commands: list[dict[str, Any]], notes: list, n_before: int, n_after: int
            ) -> tuple[int, int]:  # fmt: skip
    """(first, last) frame that may differ from the version's."""
    if n_before != n_after or any(c["op"] not in pose_edits.EDITS for c in commands):
        return 0, n_after - 1
    spans = [n["frames"] for n in notes if n is not None]
    return min(s[0] for s in spans), max(s[1] for s in spans)


def preview(conn: psycopg.Connection, clip_id: int, commands: list[dict[str, Any]]) -> dict:
    """The script's result on the clip's current version: the frames it changes and the notes."""
    if any(c.get("op") == "retarget" for c in commands):
        raise BadRequest("a preview shows a clip on its own skeleton: retarget is not previewed")
    found = conn.execute(
        "SELECT version, n_frames FROM modb.current_clips WHERE clip_id = %s", [clip_id]
    ).fetchone()
    if found is None:
        raise NotFound(f"no clip with id {clip_id} (with a version of its own)")
    version, n_frames = found
    db = WorkerDatabase(conn)
    clip = edit_clips.current_clip(db, clip_id)
    if clip is None:
        raise NotFound(f"no clip with id {clip_id}")
    sk = clip["skeleton"]
    n_result, _, largest = E.result_frames(commands, clip["rotations"].shape[0], clip["fps"])
    try:
        E.check_result_size(largest, len(sk["parents"]), len(sk["translated"]),
                            f"the preview of clip {clip_id}")  # fmt: skip
        edited, notes = E.apply_with_notes(
            clip, commands, lambda c: edit_clips.current_clip(db, c) if isinstance(c, int) else None
        )
    except E.EditError as e:
        raise BadRequest(str(e)) from None
    rotations, translations = edited["rotations"], edited["translations"]
    first, last = _window(commands, notes, clip["rotations"].shape[0], rotations.shape[0])
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
        commands = parse(EditPreview, _body(await _read(request)))["commands"]
        async with gate.turn():
            return await run_in_threadpool(answer, ident, commands)

    run.request_body = EditPreview
    return run
