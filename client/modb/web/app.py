"""`modb serve`: the browser view of the motion database (Starlette, served by uvicorn).

Read-only: its pooled connections run with default_transaction_read_only, and the database role it
is given (modb_reader is enough) bounds what it can see. Every request passes the Host/Origin guard.
"""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psycopg
from psycopg_pool import ConnectionPool
from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles

from modb.database import pgarray
from modb.database.connection import connect
from . import api
from .avatar_socket import avatar_endpoint
from .guard import HostOriginGuard, allowed_hosts

HERE = Path(__file__).parent
STATIC = HERE / "static"
# npm ci (make setup) installs the version package.json pins.
THREE = HERE / "node_modules" / "three"
log = logging.getLogger("modb.web")


class ThreeMissing(RuntimeError):
    pass


def _int(name: str, value: str | None, default: int | None = None) -> int | None:
    if value is None:
        return default
    # ASCII digits only: int() would take "1_0", "+1", "٣".
    if not re.fullmatch(r"-?[0-9]{1,18}", value):
        raise api.BadRequest(f"{name} must be an integer, got {value!r}")
    return int(value)


def _query(request: Request, *allowed: str) -> dict[str, str]:
    unknown = sorted(set(request.query_params) - set(allowed))
    if unknown:
        takes = ", ".join(allowed) if allowed else "no parameters"
        raise api.BadRequest(f"unknown parameter {unknown[0]!r}: {request.url.path} takes {takes}")
    repeated = sorted(k for k in request.query_params if len(request.query_params.getlist(k)) > 1)
    if repeated:
        raise api.BadRequest(f"parameter {repeated[0]!r} is given more than once")
    return dict(request.query_params)


def _endpoint(pool: ConnectionPool, view: Callable[[psycopg.Connection, Request], Any]) -> Callable:
    def endpoint(request: Request) -> JSONResponse:  # sync: Starlette runs it in its thread pool
        with pool.connection() as conn:
            return JSONResponse(view(conn, request))

    return endpoint


def _path_id(request: Request, what: str) -> int:
    return _int(f"{what} id", request.path_params["ident"])


def _clips(conn: psycopg.Connection, r: Request) -> Any:
    return api.clips(conn, _int("collection", _query(r, "collection").get("collection")))


def _frames(conn: psycopg.Connection, r: Request) -> Any:
    q = _query(r, "version", "start", "count")
    return api.frames(
        conn,
        _path_id(r, "clip"),
        _int("version", q.get("version")),
        _int("start", q.get("start"), 0),
        _int("count", q.get("count")),
    )


def _listing(
    view: Callable[[psycopg.Connection], Any],
) -> Callable[[psycopg.Connection, Request], Any]:
    def answer(conn: psycopg.Connection, r: Request) -> Any:
        _query(r)
        return view(conn)

    return answer


def _by_id(
    view: Callable[[psycopg.Connection, int], Any], what: str
) -> Callable[[psycopg.Connection, Request], Any]:
    def answer(conn: psycopg.Connection, r: Request) -> Any:
        _query(r)
        return view(conn, _path_id(r, what))

    return answer


VIEWS: dict[str, Callable[[psycopg.Connection, Request], Any]] = {
    "/api/collections": _listing(api.collections),
    "/api/clips": _clips,
    "/api/clips/{ident}": _by_id(api.clip, "clip"),
    "/api/clips/{ident}/frames": _frames,
    "/api/skeletons": _listing(api.skeletons),
    "/api/skeletons/{ident}": _by_id(api.skeleton, "skeleton"),
    "/api/models": _listing(api.models),
    "/api/models/{ident}": _by_id(api.model, "model"),
    "/api/graphs": _listing(api.graphs),
    "/api/graphs/{ident}": _by_id(api.graph, "graph"),
    "/api/profiles": _listing(api.profiles),
}


def _error(status: int) -> Callable:
    async def handler(request: Request, exc: Exception) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=status)

    return handler


async def _http_error(request: Request, exc: HTTPException) -> JSONResponse:
    message = f"no such page: {request.url.path}" if exc.status_code == 404 else exc.detail
    # The headers: a 405 keeps its Allow.
    return JSONResponse({"error": message}, status_code=exc.status_code, headers=exc.headers)


async def _internal_error(request: Request, exc: Exception) -> JSONResponse:
    # The details go to the server's log, not the page.
    log.exception("while answering %s", request.url.path)
    return JSONResponse(
        {"error": "internal error: the server's log says what went wrong"}, status_code=500
    )


def _configure(conn: psycopg.Connection) -> None:
    conn.autocommit = True
    conn.execute("SET default_transaction_read_only = on")
    pgarray.register(conn)


def create_app(
    conninfo: str, host: str = "127.0.0.1", port: int = 8765, allow_hosts: tuple[str, ...] = ()
) -> HostOriginGuard:
    if not (THREE / "build" / "three.module.js").exists():
        raise ThreeMissing(
            f"three.js is not installed in {THREE.parent}: run `make setup` (npm ci there)"
        )
    # Fails now, saying what to do, when the database has no modb extension.
    connect(conninfo).close()
    pool = ConnectionPool(
        conninfo,
        min_size=1,
        max_size=4,
        configure=_configure,
        open=False,
        check=ConnectionPool.check_connection,  # a restarted server costs no failed request
    )

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):
        pool.open(wait=True, timeout=10)
        yield
        pool.close()

    routes = [
        Route("/", lambda request: FileResponse(STATIC / "index.html")),
        *(Route(path, _endpoint(pool, view)) for path, view in VIEWS.items()),
        Route("/avatar", lambda request: FileResponse(STATIC / "avatar.html")),
        WebSocketRoute("/ws/avatar", avatar_endpoint(conninfo, pool)),
        Mount("/static", StaticFiles(directory=STATIC)),
        Mount("/vendor/three", StaticFiles(directory=THREE)),
    ]
    app = Starlette(
        routes=routes,
        lifespan=lifespan,
        exception_handlers={
            api.NotFound: _error(404),
            api.BadRequest: _error(400),
            HTTPException: _http_error,
            Exception: _internal_error,
        },
    )
    return HostOriginGuard(app, allowed_hosts(host, port, allow_hosts))
