"""`modb serve`: the browser view of the motion database (Starlette, served by uvicorn).

Reads run on pooled connections with default_transaction_read_only, as the role it is given
(modb_reader is enough). Writes need a loader token and run as the writer role (writes.py,
catalog_writes.py). Every request passes the Host/Origin guard.

Frame requests are the heavy ones (the database reads the clip version's arrays, this process runs
the forward kinematics and writes up to MAX_FRAMES frames of JSON): at most HEAVY_SLOTS are answered
at once, so that the other pooled connections stay free for the light reads, and at most
HEAVY_QUEUE more wait (up to HEAVY_WAIT_S) for a slot. Beyond that the answer is 503 with
Retry-After, at once.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psycopg
from psycopg_pool import ConnectionPool, PoolTimeout
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles

from modb.database import pgarray
from modb.database.connection import connect
from modb.database.read_nodes import ReadNodes
from . import (
    api,
    body_models,
    catalog_writes,
    database_errors,
    downloads,
    edit_preview,
    job_routes,
    model_graph_routes,
    model_routes,
    models_at_start,
    openapi,
)
from .avatar_socket import avatar_endpoint, default_max_avatars
from .auth import Tokens
from .bodies import Invalid
from .guard import HostOriginGuard, allowed_hosts
from .server_pool import ServerPool, Unreachable, probe
from .writes import MAX_UPLOAD_MB, WRITER_ROLE, Writer, meta_endpoints, upload_endpoint

HERE = Path(__file__).parent
STATIC = HERE / "static"
# npm ci (make setup) installs the version package.json pins.
THREE = HERE / "node_modules" / "three"
log = logging.getLogger("modb.web")

POOL_SIZE = 4  # database connections for the JSON endpoints and the avatar sockets' checks
HEAVY_SLOTS = 2  # frame requests answered at once: the other connections stay for the light reads
HEAVY_QUEUE = 16  # frame requests that may wait for a slot; more are answered 503 at once
HEAVY_WAIT_S = 30  # a frame request that waits this long for a slot is answered 503
PREVIEW_SLOTS, PREVIEW_QUEUE = 2, 8  # edit previews computed at once, and waiting for a turn
RETRY_AFTER_S = database_errors.RETRY_AFTER_S  # the 503's Retry-After
POOL_WAIT_S = 30  # a request that waits this long for a database connection is answered 503
STATEMENT_TIMEOUT = "30s"  # a pooled connection's query that takes longer is cancelled (a 503)


class ThreeMissing(RuntimeError):
    pass


class Busy(RuntimeError):
    """The server is answering as many requests of this kind as it takes: a 503, try again."""


def _int(name: str, value: str | None, default: int | None = None) -> int | None:
    if value is None:
        return default
    # ASCII digits only: int() would take "1_0", "+1", "٣".
    if not re.fullmatch(r"-?[0-9]+", value):
        raise api.BadRequest(f"{name} must be an integer, got {value!r}")
    if len(value.lstrip("-")) > 18:  # 18 digits fit the database's bigint
        raise api.BadRequest(f"{name} must be an integer of at most 18 digits, got {value}")
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


class Gate:
    """At most `slots` requests inside at once and at most `queue` more waiting (each up to
    `wait_s` seconds) for their turn; others are Busy at once. Used on the event loop only."""

    def __init__(self, what: str, slots: int, queue: int, wait_s: float) -> None:
        self.what, self.slots, self.queue, self.wait_s = what, slots, queue, wait_s
        self._free = asyncio.Semaphore(slots)
        self.waiting = 0

    @contextlib.asynccontextmanager
    async def turn(self):
        if self._free.locked() and self.waiting >= self.queue:
            raise Busy(
                f"busy: {self.slots} {self.what} are being answered and {self.waiting} more wait: "
                f"try again in {RETRY_AFTER_S} s"
            )
        self.waiting += 1
        try:
            await asyncio.wait_for(self._free.acquire(), self.wait_s)
        except TimeoutError:
            raise Busy(
                f"busy: no turn for {self.what} in {self.wait_s:g} s: "
                f"try again in {RETRY_AFTER_S} s"
            ) from None
        finally:
            self.waiting -= 1
        try:
            yield
        finally:
            self._free.release()


View = Callable[[psycopg.Connection, Request], Any]


def _endpoint(pool: ConnectionPool, view: View, tokens: Tokens) -> Callable:
    def endpoint(request: Request) -> JSONResponse:  # sync: Starlette runs it in its thread pool
        tokens.reader(request)
        with pool.connection() as conn:
            answer = view(conn, request)
        return answer if isinstance(answer, Response) else JSONResponse(answer)

    return endpoint


def _gated_endpoint(
    pool: ConnectionPool, view: View, check: Callable[[Request], Any], gate: Gate, tokens: Tokens
) -> Callable:
    """A heavy view: its arguments checked first (a bad request waits for nothing), then its turn
    at the gate, then a thread and a pooled connection."""
    answer = _endpoint(pool, view, tokens)

    async def endpoint(request: Request) -> JSONResponse:
        check(request)
        async with gate.turn():
            return await run_in_threadpool(answer, request)

    return endpoint


def _path_id(request: Request, what: str) -> int:
    return _int(f"{what} id", request.path_params["ident"])


def _clips(conn: psycopg.Connection, r: Request) -> Any:
    q = _query(r, "collection", "tag", "annotation")
    return api.clips(
        conn, _int("collection", q.get("collection")), q.get("tag"), q.get("annotation")
    )


def _processed(conn: psycopg.Connection, r: Request) -> Any:
    q = _query(r, "collection", "primitive")
    return api.processed_data(conn, q.get("collection"), q.get("primitive"))


def _frames_args(r: Request) -> tuple[int, int | None, int, int | None]:
    q = _query(r, "version", "start", "count")
    clip_id, version = _path_id(r, "clip"), _int("version", q.get("version"))
    start, count = _int("start", q.get("start"), 0), _int("count", q.get("count"))
    api.check_page(start, count)
    return clip_id, version, start, count


def _frames(conn: psycopg.Connection, r: Request) -> Any:
    return api.frames(conn, *_frames_args(r))


def _download_args(r: Request) -> tuple[int, int | None, str]:
    q = _query(r, "version", "format")
    return _path_id(r, "clip"), _int("version", q.get("version")), q.get("format", "glb")


def _download(conn: psycopg.Connection, r: Request) -> Response:
    return downloads.clip_file(conn, *_download_args(r))


def _character(conn: psycopg.Connection, r: Request) -> Response:
    _query(r)
    return downloads.skeleton_character(conn, _path_id(r, "skeleton"))


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


VIEWS: dict[str, View] = {
    "/api/collections": _listing(api.collections),
    "/api/clips": _clips,
    "/api/clips/{ident}": _by_id(api.clip, "clip"),
    "/api/skeletons": _listing(api.skeletons),
    "/api/skeletons/{ident}": _by_id(api.skeleton, "skeleton"),
    "/api/models": _listing(api.models),
    "/api/models/{ident}": _by_id(api.model, "model"),
    "/api/graphs": model_graph_routes.listing,  # ?kind=models: the graphs of models
    "/api/graphs/{ident}": model_graph_routes.one,  # a graph of models with its ETag
    "/api/profiles": _listing(api.profiles),
    "/api/edit-scripts": _listing(api.edit_scripts),
    "/api/processed-data": _processed,
    "/api/processed-data/{ident}": _by_id(api.processed_row, "processed-data row"),
    "/api/motion-models": model_routes.listing,
    "/api/motion-models/{name}": model_routes.show,
    "/api/jobs": _listing(job_routes.jobs),
    "/api/jobs/{ident}": _by_id(job_routes.job, "job"),
}
# path: (view, check of its arguments before it waits for a turn)
HEAVY_VIEWS: dict[str, tuple[View, Callable[[Request], Any]]] = {
    "/api/clips/{ident}/frames": (_frames, _frames_args),
    "/api/clips/{ident}/download": (_download, _download_args),
    "/api/skeletons/{ident}/character.glb": (_character, lambda r: _path_id(r, "skeleton")),
    "/api/motion-models/{name}/samples": (model_routes.samples, model_routes.samples_args),
    "/api/motion-models/{name}/examples": (model_routes.examples, model_routes.examples_args),
    "/api/graphs/{ident}/synthesis": (model_graph_routes.walk, model_graph_routes.walk_args),
}


# path: (handler, its body's model or None, makes frames) of the other POSTs (catalog_writes has
# the catalogue's)
WRITES: dict[str, tuple[Callable, Any, bool]] = {
    "/api/jobs": (job_routes.submit_job, body_models.JOB, False),
    "/api/edit-scripts/{name}/apply": (job_routes.apply_script, body_models.Targets, True),
    "/api/collections/{path:path}/retarget": (
        job_routes.retarget_collection, body_models.CollectionRetarget, False),
    "/api/collections/{path:path}/steps": (job_routes.steps_collection, None, False),
    "/api/collections/{path:path}/action": (
        job_routes.action_collection, body_models.Action, False),
    "/api/processed-data": (job_routes.align_primitive, body_models.Align, False),
    "/api/motion-models/{name}/build": (model_routes.build, body_models.ModelBuild, False),
    "/api/jobs/{ident}/cancel": (job_routes.cancel_job, None, False),
}  # fmt: skip


def _error(status: int) -> Callable:
    async def handler(request: Request, exc: Exception) -> JSONResponse:
        return JSONResponse({"error": str(exc)}, status_code=status)

    return handler


async def _http_error(request: Request, exc: HTTPException) -> JSONResponse:
    # The router's own 404 (no route) says "Not Found"; a handler's names what is missing.
    unrouted = exc.status_code == 404 and exc.detail == "Not Found"
    message = f"no such page: {request.url.path}" if unrouted else exc.detail
    # The headers: a 405 keeps its Allow.
    return JSONResponse({"error": message}, status_code=exc.status_code, headers=exc.headers)


def _unavailable(message: str) -> JSONResponse:
    return JSONResponse(
        {"error": message}, status_code=503, headers={"Retry-After": str(RETRY_AFTER_S)}
    )


async def _busy(request: Request, exc: Busy) -> JSONResponse:
    return _unavailable(str(exc))


async def _pool_timeout(request: Request, exc: PoolTimeout) -> JSONResponse:
    log.warning("no database connection for %s in %s s", request.url.path, POOL_WAIT_S)
    return _unavailable(
        f"busy: no database connection free in {POOL_WAIT_S} s: try again in {RETRY_AFTER_S} s"
    )


async def _query_canceled(request: Request, exc: psycopg.errors.QueryCanceled) -> JSONResponse:
    log.warning("query cancelled while answering %s: %s", request.url.path, exc)
    return _unavailable(
        f"the database did not answer within {STATEMENT_TIMEOUT}: try again in {RETRY_AFTER_S} s"
    )


async def _unreachable(request: Request, exc: Unreachable) -> JSONResponse:
    log.warning("%s: %s", request.url.path, exc)
    return _unavailable(f"{exc}; try again in {RETRY_AFTER_S} s")


def _database_error(conninfo: str) -> Callable:
    """Every database error the views let through: a broken connection (is the server there?), a
    cancelled query, or what database_errors says of the rest."""

    async def handler(request: Request, exc: psycopg.Error) -> JSONResponse:
        if isinstance(exc, psycopg.errors.QueryCanceled):
            return await _query_canceled(request, exc)
        if database_errors.is_connection_lost(exc):
            try:
                await run_in_threadpool(probe, conninfo)
            except Unreachable as gone:
                return await _unreachable(request, gone)
            log.warning("the database connection broke answering %s: %s", request.url.path, exc)
            return _unavailable(
                f"the connection to the database broke ({database_errors.message(exc)}): "
                f"try again in {RETRY_AFTER_S} s"
            )
        status, message = database_errors.answer(exc)
        if status == 503:
            log.warning("%s: %s", request.url.path, exc)
            return _unavailable(message)
        return JSONResponse({"error": message}, status_code=status)

    return handler


async def _internal_error(request: Request, exc: Exception) -> JSONResponse:
    # The details go to the server's log, not the page.
    log.exception("while answering %s", request.url.path)
    return JSONResponse(
        {"error": "internal error: the server's log says what went wrong"}, status_code=500
    )


def _configure(conn: psycopg.Connection) -> None:
    conn.autocommit = True
    conn.execute("SET default_transaction_read_only = on")
    conn.execute("SELECT set_config('statement_timeout', %s, false)", [STATEMENT_TIMEOUT])
    pgarray.register(conn)


def create_app(
    conninfo: str,
    host: str = "127.0.0.1",
    port: int = 8765,
    allow_hosts: tuple[str, ...] = (),
    require_token: bool = False,
    max_upload_mb: int = MAX_UPLOAD_MB,
    writer_role: str = WRITER_ROLE,
    nodes: ReadNodes | None = None,
    max_avatars: int | None = None,
    warn: Callable[[str], None] = log.warning,
) -> HostOriginGuard:
    """The app behind its Host/Origin guard; `warn` hears what the server cannot do (writes off)."""
    if not (THREE / "build" / "three.module.js").exists():
        raise ThreeMissing(
            f"three.js is not installed in {THREE.parent}: run `make setup` (npm ci there)"
        )
    # Fails now, saying what to do, when the database has no modb extension.
    connect(conninfo).close()
    # It checks each connection it hands out: a restarted server costs no failed request.
    pool = ServerPool(
        conninfo,
        min_size=1,
        max_size=POOL_SIZE,
        timeout=POOL_WAIT_S,
        configure=_configure,
        open=False,
    )

    tokens = Tokens(pool, require_token)
    writer = Writer.for_server(conninfo, writer_role)
    writes_off = writer.check()
    if writes_off:
        warn(f"writes are off on this server: {writes_off}")
    nodes = nodes or ReadNodes(conninfo)
    max_avatars = max_avatars or default_max_avatars(nodes)

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):
        pool.open(wait=True, timeout=10)
        try:  # the avatar page's first graph of models, prepared while the server answers
            models_at_start.prepare(pool)
        except (psycopg.Error, Unreachable) as e:
            warn(f"no graph of models prepared at start: {e}")
        yield
        writer.close()
        pool.close()

    frames_gate = Gate("clip frame requests", HEAVY_SLOTS, HEAVY_QUEUE, HEAVY_WAIT_S)
    preview_gate = Gate("edit previews", PREVIEW_SLOTS, PREVIEW_QUEUE, HEAVY_WAIT_S)
    routes = [
        Route("/", lambda request: FileResponse(STATIC / "index.html")),
        *(Route(path, _endpoint(pool, view, tokens)) for path, view in VIEWS.items()),
        *(
            Route(path, _gated_endpoint(pool, view, check, frames_gate, tokens))
            for path, (view, check) in HEAVY_VIEWS.items()
        ),
        Route(
            "/api/clips/{clip_id}/versions/{version}/meta",
            meta_endpoints(pool, tokens, writer),
            methods=["GET", "PUT"],
        ),
        Route("/api/uploads", upload_endpoint(tokens, writer, max_upload_mb), methods=["POST"]),
        Route(
            "/api/clips/{ident}/edit-preview",
            edit_preview.endpoint(pool, tokens, preview_gate, lambda r: _path_id(r, "clip")),
            methods=["POST"],
        ),
        *catalog_writes.routes(pool, tokens, writer),
        *(
            Route(path, catalog_writes.write_endpoint(tokens, writer, *how), methods=["POST"])
            for path, how in WRITES.items()
        ),
        Route("/avatar", lambda request: FileResponse(STATIC / "avatar.html")),
        WebSocketRoute("/ws/avatar", avatar_endpoint(nodes, pool, tokens, max_avatars)),
        Mount("/static", StaticFiles(directory=STATIC)),
        Mount("/vendor/three", StaticFiles(directory=THREE)),
    ]
    routes.append(Route("/api/openapi.json", openapi.endpoint(routes)))  # (it reads the others)
    app = Starlette(
        routes=routes,
        lifespan=lifespan,
        exception_handlers={
            api.NotFound: _error(404),
            api.BadRequest: _error(400),
            Invalid: _error(400),
            Busy: _busy,
            PoolTimeout: _pool_timeout,
            Unreachable: _unreachable,
            psycopg.Error: _database_error(conninfo),
            HTTPException: _http_error,
            Exception: _internal_error,
        },
    )
    return HostOriginGuard(app, allowed_hosts(host, port, allow_hosts))
