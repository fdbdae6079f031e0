"""The WebSocket /ws/avatar: avatar mode's asyncio side (AvatarSession does the work in threads).

The Host/Origin guard in front refuses a foreign page before this runs. Each connection gets its own
database session; at most MAX_AVATARS walk at once, so tabs cannot exhaust the server's connections.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
from collections.abc import Callable
from typing import Any

from psycopg_pool import ConnectionPool
from starlette.concurrency import run_in_threadpool
from starlette.websockets import WebSocket, WebSocketDisconnect

from modb.synthesis.avatar import Settings
from . import api
from .avatar_session import AvatarSession
from .avatar_settings import check_settings

log = logging.getLogger("modb.web")
MAX_AVATARS = 8  # open avatar sockets (walking or not) per server
SEND_TIMEOUT_S = 30  # a page that reads nothing for this long stops its avatar


def _defaults(choices: dict[str, Any]) -> Settings:
    # The newest transition graph: the aims of synthesis (README "Synthesis quality") need one.
    # A lead time of 0.1 s hides a selection (~20-30 ms with a graph) behind the last frames.
    return Settings(graph=choices["graphs"][0] if choices["graphs"] else None, lead_time=0.1)


def avatar_endpoint(conninfo: str, pool: ConnectionPool) -> Callable:
    slots = threading.BoundedSemaphore(MAX_AVATARS)

    def check(settings: Settings) -> None:
        with pool.connection() as conn:
            check_settings(conn, settings)

    def offered() -> dict[str, Any]:
        with pool.connection() as conn:
            return api.avatar_choices(conn)

    async def endpoint(websocket: WebSocket) -> None:
        await websocket.accept()
        if not slots.acquire(blocking=False):
            await websocket.close(
                code=1013, reason=f"{MAX_AVATARS} avatars are walking already: try again later"
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

        session: AvatarSession | None = None
        try:
            choices = await run_in_threadpool(offered)
            session = AvatarSession(conninfo, send, check, _defaults(choices))
            await websocket.send_text(
                json.dumps({"type": "ready", **choices, "settings": session.public_settings()})
            )
            while True:
                received = await websocket.receive()
                if received["type"] == "websocket.disconnect":
                    break
                try:
                    message = json.loads(received.get("text") or "")
                except json.JSONDecodeError as e:
                    await websocket.send_text(
                        json.dumps({"type": "refused", "message": f"not JSON text: {e}"})
                    )
                    continue
                await run_in_threadpool(session.handle, message)
        except WebSocketDisconnect:
            pass
        except Exception:  # the server's log has it; the page sees the socket close
            log.exception("avatar socket")
        finally:
            if session is not None:
                await run_in_threadpool(session.close)
            slots.release()

    return endpoint
