"""The REST interface's writes: uploads through the loader's own path, and a clip version's meta
(annotations, tags) with optimistic concurrency. Each needs a loader token (auth.py), runs on a
connection of the writer role (a non-superuser login role that is a member of modb_loader; never a
superuser's SET ROLE) and is recorded in modb.audit_log in the same transaction."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import psycopg
from psycopg.conninfo import make_conninfo
from psycopg_pool import ConnectionPool
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import FormData
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse

from modb.access import audit
from modb.access.tokens import Grant
from modb.database import pgarray
from modb.database.cluster import WRITER_ROLE
from modb.loader.annotations import AnnotationError
from modb.loader.errors import MotionFileError
from modb.loader.folders import NamedFiles
from modb.loader.ingest import load_files
from modb.loader.reading import ReadOptions
from modb.loader.sources import named_sources
from modb.editing.meta import (
    MAX_META_BYTES,
    MetaNotFound,
    StaleMeta,
    VersionMeta,
    read_meta,
    write_meta,
)

from .api import NotFound
from .auth import Tokens
from .bodies import authorized_json, parse
from .body_models import PATH
from .body_models import VersionMeta as MetaBody
from .server_pool import ServerPool

MAX_UPLOAD_MB = 100  # a request's body; `modb serve --max-upload-mb` changes it
MAX_UPLOAD_FILES = 500
UPLOAD_SUFFIXES = (".bvh", ".amc", ".asf", ".annotations.json")  # loader/sidecars.py
SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._ -]{0,200}$")
WRITE_TIMEOUT = "10min"  # a large file's snippets take a while


class WritesOff(HTTPException):
    def __init__(self, why: str) -> None:
        super().__init__(503, f"writes are off on this server: {why}")


@dataclass
class Writer:
    """The writer role's connections; refused (503, saying why) when the role cannot log in, is a
    superuser or is not a member of modb_loader. `modb serve` checks that at start-up (check()),
    so that it can say so then, not only at the first write."""

    conninfo: str
    role: str
    _pool: ConnectionPool | None = None
    _why_not: str | None = None
    _checked: bool = False

    @classmethod
    def for_server(cls, conninfo: str, role: str = WRITER_ROLE) -> Writer:
        return cls(make_conninfo(conninfo, user=role), role)

    def _configure(self, conn: psycopg.Connection) -> None:
        conn.autocommit = True
        pgarray.register(conn)  # the loader sends its arrays as binary float4
        conn.execute("SELECT set_config('statement_timeout', %s, false)", [WRITE_TIMEOUT])

    def check(self) -> str | None:
        """Why writes are off on this server (None: they are on). Asked once: a role created
        later takes a restart of `modb serve`."""
        if self._checked:
            return self._why_not
        try:
            with psycopg.connect(self.conninfo, connect_timeout=10) as conn:
                superuser, loader = conn.execute(
                    "SELECT rolsuper, pg_has_role(current_user, 'modb_loader', 'MEMBER') "
                    "FROM pg_roles WHERE rolname = current_user"
                ).fetchone()
        except psycopg.Error as e:
            reason = " ".join(str(e).split())[:200]
            self._why_not = (
                f"the writer role {self.role} cannot connect ({reason}); create it "
                f"(CREATE ROLE {self.role} LOGIN IN ROLE modb_loader, with a password on a "
                f"server that asks one) or name another with --write-user, then restart modb serve"
            )
        else:
            if superuser or not loader:
                self._why_not = (
                    f"the writer role {self.role} must be a member of modb_loader and not a "
                    f"superuser"
                )
        self._checked = True
        return self._why_not

    def pool(self) -> ConnectionPool:
        if self.check():
            raise WritesOff(self._why_not)
        if self._pool is None:
            self._pool = ServerPool(
                self.conninfo, min_size=0, max_size=2, configure=self._configure, open=True
            )
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()


def _version_meta_body(m: VersionMeta) -> JSONResponse:
    return JSONResponse(
        {"clip_id": m.clip_id, "version": m.version, "n_frames": m.n_frames, "meta": m.meta},
        headers={"ETag": m.etag},
    )


def _path_ints(request: Request) -> tuple[int, int]:
    try:
        return int(request.path_params["clip_id"]), int(request.path_params["version"])
    except ValueError:
        raise HTTPException(400, "clip and version are whole numbers") from None


def meta_endpoints(read_pool: ConnectionPool, tokens: Tokens, writer: Writer):
    """GET and PUT /api/clips/{clip_id}/versions/{version}/meta."""

    def get(request: Request) -> JSONResponse:
        tokens.reader(request)
        clip_id, version = _path_ints(request)
        with read_pool.connection() as conn:
            try:
                return _version_meta_body(read_meta(conn, clip_id, version))
            except MetaNotFound as e:
                raise NotFound(str(e)) from None

    def put(request: Request, grant, body: Any) -> JSONResponse:
        clip_id, version = _path_ints(request)
        if_match = request.headers.get("if-match")
        if not if_match:
            raise HTTPException(
                428, "send If-Match with the ETag of the meta you read, so no edit is lost"
            )
        body = parse(MetaBody, body)  # {"meta": the whole new meta}

        def audited(conn: psycopg.Connection, written: VersionMeta) -> None:
            audit.record(
                conn,
                grant.name,
                "meta",
                f"clip {clip_id} version {version}",
                {"annotations": len(written.meta.get("annotations", [])), "etag": written.etag},
            )

        with writer.pool().connection() as conn:
            try:
                written = write_meta(conn, clip_id, version, body["meta"], if_match, audited)
            except MetaNotFound as e:
                raise NotFound(str(e)) from None
            except StaleMeta as e:
                return JSONResponse(
                    {"error": str(e), "meta": e.current.meta},
                    status_code=409,
                    headers={"ETag": e.current.etag},
                )
            except AnnotationError as e:
                raise HTTPException(400, str(e)) from None
            except psycopg.DataError as e:  # e.g. a \u0000 in a string, which jsonb refuses
                raise HTTPException(400, f"meta: {e.diag.message_primary or e}") from None
        return _version_meta_body(written)

    async def endpoint(request: Request) -> JSONResponse:
        if request.method == "GET":
            return await run_in_threadpool(get, request)
        grant, body = await authorized_json(request, tokens, MAX_META_BYTES + 1024)
        return await run_in_threadpool(put, request, grant, body)

    endpoint.request_body = MetaBody  # (the PUT's)
    return endpoint


def _uploaded_files(form: FormData) -> NamedFiles:
    """The form's files by their own names (checked: no paths), read where the form spooled them:
    the loader reads each once from there, with no folder written or walked."""
    files: dict[str, BinaryIO] = {}
    for field_name, value in form.multi_items():
        if isinstance(value, str):
            continue
        name = Path(value.filename or "").name
        if not SAFE_NAME.match(name) or not name.lower().endswith(UPLOAD_SUFFIXES):
            raise HTTPException(
                400,
                f"{name or field_name!r:.80}: upload .bvh, .amc with .asf, and .annotations.json "
                f"files named with letters, digits, '.', '_', '-' or spaces",
            )
        if name in files:
            raise HTTPException(400, f"{name}: given twice")
        files[name] = value.file
    return NamedFiles(files)


def _load_upload(
    writer: Writer, grant: Grant, collection: str, files: NamedFiles
) -> dict[str, Any]:
    """Each motion file through the loader's own load, with its audit row in its transaction."""
    try:
        sources = named_sources(files, collection)
    except MotionFileError as e:
        raise HTTPException(400, str(e)) from None
    if not sources:
        raise HTTPException(400, "no motion file (.bvh, .amc) in the upload")
    options = ReadOptions()  # one per upload: an ASF shared by its AMC files is read once
    results = []
    with writer.pool().connection() as conn:
        try:
            for source in sources:
                with conn.transaction():  # the file, its snippets and its audit row together
                    r = load_files(conn, [source], options, keep_going=True).results[0]
                    if r.status == "loaded":
                        audit.record(
                            conn,
                            grant.name,
                            "upload",
                            f"clip {r.clip_id} version {r.version}",
                            {
                                "file": source.path.name,
                                "collection": collection,
                                "frames": r.frames,
                            },
                        )
                results.append(
                    {
                        "file": source.path.name,
                        "status": r.status,
                        "clip_id": r.clip_id,
                        "version": r.version,
                        "frames": r.frames,
                        "snippets": r.snippets,
                        "message": r.message,
                    }
                )
        finally:
            conn.close()  # its snippets were built there: a fresh process next (write_endpoint)
    return {"collection": collection, "results": results}


def upload_endpoint(tokens: Tokens, writer: Writer, max_upload_mb: int):
    """POST /api/uploads: multipart files (BVH, or AMC with their ASF) and a `collection` field."""
    limit = max_upload_mb << 20

    async def endpoint(request: Request) -> JSONResponse:
        grant = await run_in_threadpool(tokens.writer, request)
        length = request.headers.get("content-length")
        if length is None or not length.isdigit():
            raise HTTPException(411, "send Content-Length")
        if int(length) > limit:
            raise HTTPException(
                413, f"the upload is larger than this server's limit of {max_upload_mb} MB"
            )
        if not request.headers.get("content-type", "").startswith("multipart/form-data"):
            raise HTTPException(400, "upload files as multipart/form-data")
        try:
            form = await request.form(max_files=MAX_UPLOAD_FILES, max_fields=10)
        except HTTPException:
            raise
        except Exception as e:  # python-multipart's parse errors
            raise HTTPException(400, f"a malformed multipart body: {e}") from None
        try:
            given = form.get("collection") or "uploads"
            if not isinstance(given, str):
                raise HTTPException(400, "collection: a form field, not a file")
            collection = parse(PATH, given.strip(), "collection")
            files = _uploaded_files(form)
            answer = await run_in_threadpool(_load_upload, writer, grant, collection, files)
        finally:
            await form.close()
        stored = any(r["status"] in ("loaded", "unchanged") for r in answer["results"])
        return JSONResponse(answer, status_code=200 if stored else 400)

    return endpoint
