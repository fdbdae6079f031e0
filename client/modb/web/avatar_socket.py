"""The WebSocket /ws/avatar: avatar mode's asyncio side (AvatarSession, or ModelAvatarSession on a
graph of models, does the work in threads; a "mode" message switches from one to the other).

The Host/Origin guard in front refuses a foreign page before this runs. Each connection gets its own
database session; at most `max_avatars` are open at once (by default MAX_AVATARS_PER_NODE for each
database node), so tabs cannot exhaust the nodes' connections or the server's CPU.
A message longer than MAX_MESSAGE_BYTES or nested deeper than MAX_MESSAGE_DEPTH is refused before
it is parsed (json.loads recurses once per level), and the socket goes on.
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import threading
from collections.abc import Callable
from typing import Any

from psycopg_pool import ConnectionPool
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.websockets import WebSocket, WebSocketDisconnect

from modb_kernel.database import StoreError

from modb.database.read_nodes import ReadNodes
from modb.synthesis.avatar import Settings
from . import api, models_at_start
from .auth import Tokens

from .avatar_session import AvatarSession
from .avatar_settings import check_settings
from .avatar_standing import standing_messages
from .model_avatar_session import ModelAvatarSession, checked_mode

log = logging.getLogger("modb.web")
MAX_AVATARS_PER_NODE = 8  # open avatar sockets (walking or not) per database node, by default
SEND_TIMEOUT_S = 30  # a page that reads nothing for this long stops its avatar
MAX_MESSAGE_BYTES = 64 * 1024  # the page's messages (goals, settings) are well under 1 KiB
MAX_MESSAGE_DEPTH = 8  # arrays and objects within each other; the protocol's messages need 2
AUTH_WAIT_S = 10  # with --require-token: how long the page has to send its token
CLOSE_UNAUTHORIZED = 4401  # a close code of the application's range (4000-4999): 401's meaning
_SPECIAL = re.compile(r'[\\"\[\]{}]')  # what the depth scan looks at: quotes, escapes, brackets


Session = AvatarSession | ModelAvatarSession
Send = Callable[[dict[str, Any]], None]


class MessageRefused(ValueError):
    pass


def nesting_depth(text: str) -> int:
    """How deep arrays and objects nest in JSON text (brackets inside strings do not count), read
    in one pass without parsing it. Up to where a parser would stop on an error it sees what the
    parser sees, so it never counts fewer levels than json.loads would enter."""
    depth = deepest = 0
    in_string = False
    escaped = -1  # the position a backslash in a string escapes
    for found in _SPECIAL.finditer(text):
        at, char = found.start(), found.group()
        if in_string:
            if at == escaped:
                continue
            if char == "\\":
                escaped = at + 1
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth = max(0, depth - 1)
    return deepest


def parse_message(received: dict[str, Any]) -> Any:
    """The JSON value of a received text message, or MessageRefused saying what is wrong with it."""
    text = received.get("text")
    if text is None:
        raise MessageRefused("binary messages are not part of the protocol: send JSON text")
    size = len(text.encode("utf-8", "surrogatepass"))
    if size > MAX_MESSAGE_BYTES:
        raise MessageRefused(
            f"message too long: {size} bytes, the limit is {MAX_MESSAGE_BYTES} bytes"
        )
    depth = nesting_depth(text)
    if depth > MAX_MESSAGE_DEPTH:
        raise MessageRefused(
            f"message nested too deep: {depth} levels of arrays and objects, "
            f"the limit is {MAX_MESSAGE_DEPTH}"
        )
    try:
        return json.loads(text)
    except RecursionError:  # not expected after the depth check; refused all the same
        raise MessageRefused("message nested too deep to parse") from None
    except json.JSONDecodeError as e:
        raise MessageRefused(f"not JSON text: {e}") from None
    except ValueError:  # an integer of more digits than Python converts (4300)
        raise MessageRefused("a number in the message has too many digits") from None


def _defaults() -> Settings:
    # The graph left to the Avatar: the newest current one over the data (modb.default_graph).
    # A lead time of 0.25 s hides a selection (~2-30 ms) behind the last frames, on a busy machine
    # too; a goal after the query started asks again, so the lead delays no answer.
    return Settings(lead_time=0.25)


async def _authorized(websocket: WebSocket, tokens: Tokens) -> bool:
    """With --require-token, the page's first message is {"type": "auth", "token": ...} (a browser
    cannot set headers on a WebSocket, and a token never goes in a URL); else the socket closes."""
    if not tokens.require_for_reads:
        return True
    try:
        received = await asyncio.wait_for(websocket.receive(), AUTH_WAIT_S)
        message = parse_message(received)
        token = message.get("token") if isinstance(message, dict) else None
        if not (isinstance(message, dict) and message.get("type") == "auth"):
            raise MessageRefused('send {"type": "auth", "token": ...} first')
        await run_in_threadpool(tokens.check, token if isinstance(token, str) else None)
        return True
    except (asyncio.TimeoutError, MessageRefused, HTTPException, KeyError) as e:
        why = getattr(e, "detail", None) or str(e) or "no token sent in time"
        await websocket.close(
            code=CLOSE_UNAUTHORIZED, reason=f"this server needs a token: {why}"[:120]
        )
        return False


def _mode(session: Session) -> dict[str, Any]:
    if isinstance(session, ModelAvatarSession):
        return {"models": session.graph, "seed": session.seed}
    return {"models": None, "seed": None}


def default_max_avatars(nodes: ReadNodes) -> int:
    return MAX_AVATARS_PER_NODE * (1 + len(nodes.standbys))


def avatar_endpoint(
    nodes: ReadNodes, pool: ConnectionPool, tokens: Tokens, max_avatars: int
) -> Callable:
    slots = threading.BoundedSemaphore(max_avatars)

    def check(settings: Settings) -> None:
        with pool.connection() as conn:
            check_settings(conn, settings)

    def offered() -> dict[str, Any]:
        """What the page can choose, and the avatar standing before its first goal."""
        with pool.connection() as conn:
            return {**api.avatar_choices(conn), "standing": standing_messages(conn)}

    def switch(session: Session, message: dict[str, Any], send: Send, kept: list) -> Session:
        """The session of the mode a "mode" message asks for (the current one goes on when the
        message is refused): on a graph of models {"models": name, "seed": int, "goals":
        [[x, z], ...]}, else motion matching ({"models": null}), with the settings it had last
        on this connection (`kept`). The new one stands at the origin."""
        try:
            models, seed, goals = checked_mode(message)
            if isinstance(session, AvatarSession):
                kept[0] = session.settings
            if models is None:
                new: Session = AvatarSession(nodes, send, check, kept[0])
                with pool.connection() as conn:
                    standing = standing_messages(conn)
            else:
                # its models prepared as the server started: waited for (holding no connection
                # meanwhile), not prepared a second time beside it
                models_at_start.wait_for(models)
                with pool.connection() as conn:
                    new = ModelAvatarSession(conn, send, models, seed, goals)
                standing = []
        except (ValueError, StoreError) as e:  # StoreError: no such graph; ValueError: a broken one
            hint = getattr(e, "hint", None)
            why = f"no mode change: {e}" + (f" ({hint})" if hint else "")
            send({"type": "refused", "message": why, "mode": _mode(session)})
            return session
        session.close()
        # on models: the graph's actions, which the page offers beside the mode
        on_models = isinstance(new, ModelAvatarSession)
        send({"type": "mode", **_mode(new), "settings": new.public_settings(),
              "actions": new.actions if on_models else [],
              "repeated_actions": new.repeated_actions if on_models else []})  # fmt: skip
        for m in standing:
            send(m)
        if isinstance(new, ModelAvatarSession):
            new.start()
        return new

    async def endpoint(websocket: WebSocket) -> None:
        await websocket.accept()
        if not await _authorized(websocket, tokens):
            return
        if not slots.acquire(blocking=False):
            await websocket.close(
                code=1013,
                reason=f"{max_avatars} avatars are open already (modb serve --max-avatars): "
                "try again later",
            )
            return
        loop = asyncio.get_running_loop()

        def send(message: dict[str, Any]) -> None:  # from the session's threads
            text = json.dumps(message, allow_nan=False)
            future = asyncio.run_coroutine_threadsafe(websocket.send_text(text), loop)
            try:
                future.result(SEND_TIMEOUT_S)
            except BaseException:
                future.cancel()
                raise

        session: Session | None = None
        try:
            session = AvatarSession(nodes, send, check, _defaults())
            kept = [session.settings]  # motion matching's settings, while on a graph of models
            # the standing avatar comes in the ready message (its first message stays "ready", and
            # a script's next message answers what it sent)
            choices = await run_in_threadpool(offered)
            ready = {"type": "ready", **choices, "mode": _mode(session)}
            await websocket.send_text(json.dumps({**ready, "settings": session.public_settings()}))
            while True:
                received = await websocket.receive()
                if received["type"] == "websocket.disconnect":
                    break
                try:
                    message = parse_message(received)
                except MessageRefused as e:
                    await websocket.send_text(json.dumps({"type": "refused", "message": str(e)}))
                    continue
                if isinstance(message, dict) and message.get("type") == "auth":
                    continue  # the page sends its token whether or not the server asks for one
                try:
                    if isinstance(message, dict) and message.get("type") == "mode":
                        session = await run_in_threadpool(switch, session, message, send, kept)
                    else:
                        await run_in_threadpool(session.handle, message)
                except Exception:  # a bug: the server's log has it; the page may go on
                    log.exception("avatar message %.200r", message)
                    await websocket.send_text(
                        json.dumps(
                            {
                                "type": "refused",
                                "message": "the server could not handle that message "
                                "(its log says why)",
                            }
                        )
                    )
        except WebSocketDisconnect:
            pass
        except Exception:  # the server's log has it; the page sees the socket close
            log.exception("avatar socket")
        finally:
            if session is not None:
                await run_in_threadpool(session.close)
            slots.release()

    return endpoint
