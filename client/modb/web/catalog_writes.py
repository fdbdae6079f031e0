"""The REST interface's catalogue writes: collections (create, rename, move, delete), clips and
versions (delete, make an older version current), a skeleton's joint map and mirror pairs (with an
ETag), and `models` and `graphs` rows (create, replace, delete). Like every write: a loader token,
the writer role's connection, one transaction with its modb.audit_log row, and errors as
400/404/409 with the database's message."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg import errors, sql
from psycopg.types.json import Jsonb
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse
from starlette.routing import Route

from modb.access import audit
from modb.clips import collection_clips
from modb.editing import catalog

from .auth import Tokens
from .bodies import authorized_json
from .writes import Writer

MAX_DOCUMENT_BYTES = 64 << 20  # a model's or graph's data, as JSON


@dataclass
class Done:
    """A write's answer and its audit record (action, object, detail)."""

    body: dict[str, Any]
    action: str
    obj: str
    detail: dict[str, Any]
    status: int = 200
    headers: dict[str, str] | None = None


Handler = Callable[[psycopg.Connection, Request, Any], Done]


@contextlib.contextmanager
def _database_errors() -> Iterator[None]:
    """The database's refusals as HTTP answers with its message and hint."""
    try:
        yield
    except psycopg.OperationalError:
        raise
    except psycopg.Error as e:
        message = e.diag.message_primary or str(e)
        if e.diag.message_hint:
            message += f" ({e.diag.message_hint})"
        status = (
            404
            if isinstance(e, errors.NoDataFound)
            else 409
            if isinstance(e, (errors.UniqueViolation, errors.DependentObjectsStillExist))
            else 400
        )
        raise HTTPException(status, message) from None


def _int(request: Request, name: str) -> int:
    try:
        return int(request.path_params[name])
    except ValueError:
        raise HTTPException(400, f"{name} is a whole number") from None


def _object(body: Any, *required: str) -> dict[str, Any]:
    if not isinstance(body, dict):
        raise HTTPException(400, "the body is a JSON object")
    missing = [k for k in required if k not in body]
    if missing:
        raise HTTPException(400, f"the body needs {', '.join(missing)}")
    return body


def _text(body: dict[str, Any], key: str, required: bool = True) -> str | None:
    value = body.get(key)
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value.strip() or len(value) > 200:
        raise HTTPException(400, f"{key}: a string of 1 to 200 characters")
    return value


def write_endpoint(tokens: Tokens, writer: Writer, handler: Handler, with_body: bool = True):
    """An endpoint running `handler` as one audited transaction of the writer role."""

    def run(request: Request, grant, body: Any) -> JSONResponse:
        with writer.pool().connection() as conn, _database_errors():
            with conn.transaction():
                done = handler(conn, request, body)
                audit.record(conn, grant.name, done.action, done.obj, done.detail)
        return JSONResponse(done.body, status_code=done.status, headers=done.headers)

    async def endpoint(request: Request) -> JSONResponse:
        grant, body = await authorized_json(request, tokens, MAX_DOCUMENT_BYTES, with_body)
        return await run_in_threadpool(run, request, grant, body)

    return endpoint


# Collections


def _create_collection(conn, request, body) -> Done:
    path = _text(_object(body, "path"), "path")
    existed = catalog.find_collection(conn, path) is not None
    found, shown = catalog.create_collection(conn, path)
    return Done(
        {"id": found, "path": shown}, "collection create", shown, {}, 200 if existed else 201
    )


def _change_collection(conn, request, body) -> Done:
    path = request.path_params["path"]
    body = _object(body)
    if not {"name", "parent"} & body.keys():
        raise HTTPException(
            400, 'the body has "name" (rename) and/or "parent" (move; "" for the top)'
        )
    shown = path
    if "parent" in body:
        parent = body["parent"]
        if parent is not None and not isinstance(parent, str):
            raise HTTPException(400, "parent: a collection path, or '' for the top")
        shown = catalog.move_collection(conn, shown, parent)
    if "name" in body:
        shown = catalog.rename_collection(conn, shown, _text(body, "name"))
    return Done({"path": shown}, "collection change", path, {"now": shown})


def _delete_collection(conn, request, body) -> Done:
    path = request.path_params["path"]
    with_clips = request.query_params.get("with_clips", "false").lower() in ("1", "true", "yes")
    clips = catalog.delete_collection(conn, path, with_clips)
    return Done({"deleted": path, "clips": clips}, "collection delete", path, {"clips": clips})


# Clips and versions


def _delete_clip(conn, request, body) -> Done:
    clip_id = _int(request, "ident")
    versions = catalog.delete_clip(conn, clip_id)
    return Done(
        {"deleted": clip_id, "versions": versions},
        "clip delete",
        f"clip {clip_id}",
        {"versions": versions},
    )


def _delete_version(conn, request, body) -> Done:
    clip_id, version = _int(request, "clip_id"), _int(request, "version")
    r = catalog.delete_version(conn, clip_id, version)
    return Done(
        {"deleted": version, "current_version": r.version, "snippets": r.snippets},
        "version delete",
        f"clip {clip_id} version {version}",
        {"current_version": r.version},
    )


def _restore_version(conn, request, body) -> Done:
    clip_id, version = _int(request, "clip_id"), _int(request, "version")
    r = catalog.restore_version(conn, clip_id, version)
    return Done(
        {"restored": version, "current_version": r.version, "snippets": r.snippets},
        "version restore",
        f"clip {clip_id} version {version}",
        {"current_version": r.version},
        201,
    )


# A skeleton's joint map and mirror pairs


def _maps_body(maps: catalog.SkeletonMaps, **extra: Any) -> dict[str, Any]:
    return {"skeleton_id": maps.skeleton_id, **maps.document, **extra}


def maps_endpoint(read_pool, tokens: Tokens, writer: Writer):
    """GET and PUT /api/skeletons/{skeleton_id}/maps (PUT needs If-Match, like a version's meta)."""
    put = write_endpoint(tokens, writer, _put_maps)

    def get(request: Request) -> JSONResponse:
        tokens.reader(request)
        with read_pool.connection() as conn:
            try:
                maps = catalog.read_maps(conn, _int(request, "skeleton_id"))
            except catalog.SkeletonNotFound as e:
                raise HTTPException(404, str(e)) from None
        return JSONResponse(_maps_body(maps), headers={"ETag": maps.etag})

    async def endpoint(request: Request) -> JSONResponse:
        if request.method == "GET":
            return await run_in_threadpool(get, request)
        return await put(request)

    return endpoint


def _put_maps(conn, request, body) -> Done:
    skeleton_id = _int(request, "skeleton_id")
    if_match = request.headers.get("if-match")
    if not if_match:
        raise HTTPException(428, "send If-Match with the ETag of the maps you read")
    body = _object(body, "joint_map", "mirror_pairs")
    axes = body.get("joint_axes")
    if axes is not None and not isinstance(axes, dict):
        raise HTTPException(400, 'joint_axes: {} or {"joints": {...}, "pose": ...}')
    try:
        maps, recut = catalog.write_maps(
            conn, skeleton_id, body["joint_map"], body["mirror_pairs"], if_match, axes
        )
    except catalog.SkeletonNotFound as e:
        raise HTTPException(404, str(e)) from None
    except catalog.StaleMaps as e:
        raise _Stale(e) from None
    return Done(
        _maps_body(maps, clips_recut=len(recut), snippets=sum(r.snippets for r in recut)),
        "skeleton maps",
        f"skeleton {skeleton_id}",
        {"clips_recut": len(recut)},
        headers={"ETag": maps.etag},
    )


class _Stale(HTTPException):
    def __init__(self, e: catalog.StaleMaps) -> None:
        super().__init__(409, str(e), headers={"ETag": e.current.etag})


# models and graphs rows

# Transition graphs are built from the snippets by modb.build_transition_graph (`modb graph build`):
# a hand-written one could name successors the selection would trust. They can only be deleted here.
BUILT_KINDS = ("transitions",)


def _row_fields(body: Any, table: str, partial: bool) -> dict[str, Any]:
    body = _object(body, *(() if partial else ("name", "kind", "data")))
    fields: dict[str, Any] = {}
    for key in ("name", "kind"):
        if key in body:
            fields[key] = _text(body, key)
    if fields.get("kind") in BUILT_KINDS and table == "graphs":
        raise HTTPException(400, "transition graphs are built: `modb graph build NAME`")
    if "data" in body:
        fields["data"] = Jsonb(body["data"])
    if "meta" in body:
        if not isinstance(body["meta"], dict):
            raise HTTPException(400, "meta: a JSON object")
        fields["meta"] = Jsonb(body["meta"])
    if "skeleton_id" in body:
        if body["skeleton_id"] is not None and not isinstance(body["skeleton_id"], int):
            raise HTTPException(400, "skeleton_id: a skeleton's id, or null")
        fields["skeleton_id"] = body["skeleton_id"]
    if not fields:
        raise HTTPException(400, "nothing to change: give name, kind, data, meta or skeleton_id")
    return fields


def _create_row(table: str):
    def handler(conn, request, body) -> Done:
        fields = _row_fields(body, table, partial=False)
        if (
            table == "graphs"
        ):  # a graph's name is also its row in modb.graph_names (83_graphs.sql)
            conn.execute(
                "INSERT INTO modb.graph_names (name, kind) VALUES (%s, %s)",
                [fields["name"], fields["kind"]],
            )
        (made,) = conn.execute(
            sql.SQL("INSERT INTO {} ({}) VALUES ({}) RETURNING id").format(
                sql.Identifier("modb", table),
                sql.SQL(", ").join(map(sql.Identifier, fields)),
                sql.SQL(", ").join([sql.Placeholder()] * len(fields)),
            ),
            list(fields.values()),
        ).fetchone()
        return Done(
            {"id": made, "name": fields["name"], "kind": fields["kind"]},
            f"{table[:-1]} create",
            f"{table[:-1]} {made}",
            {"name": fields["name"], "kind": fields["kind"]},
            201,
        )

    return handler


def _row(conn, table: str, ident: int) -> tuple[str, str]:
    row = conn.execute(
        sql.SQL("SELECT name, kind FROM {} WHERE id = %s FOR UPDATE").format(
            sql.Identifier("modb", table)
        ),
        [ident],
    ).fetchone()
    if row is None:
        raise HTTPException(404, f"no {table[:-1]} with id {ident}")
    return row


def _replace_row(table: str):
    def handler(conn, request, body) -> Done:
        ident = _int(request, "ident")
        name, kind = _row(conn, table, ident)
        fields = _row_fields(body, table, partial=True)
        if table == "graphs" and (kind in BUILT_KINDS or {"name", "kind"} & fields.keys()):
            raise HTTPException(
                400,
                "a graph's name and kind stay; a transition graph is rebuilt, not replaced "
                "(`modb graph build NAME`)",
            )
        assignments = sql.SQL(", ").join(
            sql.SQL("{} = %s").format(sql.Identifier(k)) for k in fields
        )
        conn.execute(
            sql.SQL("UPDATE {} SET {} WHERE id = %s").format(
                sql.Identifier("modb", table), assignments
            ),
            [*fields.values(), ident],
        )
        return Done(
            {"id": ident, "replaced": sorted(fields)},
            f"{table[:-1]} replace",
            f"{table[:-1]} {ident}",
            {"fields": sorted(fields), "name": name, "kind": kind},
        )

    return handler


def _delete_row(table: str):
    def handler(conn, request, body) -> Done:
        ident = _int(request, "ident")
        name, kind = _row(conn, table, ident)
        if table == "graphs":  # its rows go with its name (ON DELETE CASCADE)
            conn.execute("DELETE FROM modb.graph_names WHERE name = %s AND kind = %s", [name, kind])
        else:
            conn.execute("DELETE FROM modb.models WHERE id = %s", [ident])
        return Done(
            {"deleted": ident},
            f"{table[:-1]} delete",
            f"{table[:-1]} {ident}",
            {"name": name, "kind": kind},
        )

    return handler


# Edit scripts and retargeting (modb.apply_edit_script, modb.retarget)


def _put_script(conn, request, body) -> Done:
    name = request.path_params["name"]
    body = _object(body, "commands")
    if not isinstance(body["commands"], list) or not body["commands"]:
        raise HTTPException(400, "commands: a non-empty list of commands")
    comment = body.get("comment")
    if comment is not None and not isinstance(comment, str):
        raise HTTPException(400, "comment: a string")
    (made,) = conn.execute(
        "INSERT INTO modb.edit_scripts (name, commands, comment) VALUES (%s, %s, %s) "
        "ON CONFLICT (name) DO UPDATE SET commands = EXCLUDED.commands, "
        "comment = EXCLUDED.comment RETURNING xmax = 0",
        [name, Jsonb(body["commands"]), comment],
    ).fetchone()
    return Done(
        {"name": name, "commands": len(body["commands"])},
        "edit script save",
        name,
        {"commands": body["commands"]},
        201 if made else 200,
    )


def _delete_script(conn, request, body) -> Done:
    name = request.path_params["name"]
    if conn.execute("DELETE FROM modb.edit_scripts WHERE name = %s", [name]).rowcount == 0:
        raise HTTPException(404, f"no edit script {name!r}")
    return Done({"deleted": name}, "edit script delete", name, {})


def _target_clips(conn, body) -> list[int]:
    if "collection" in body:
        path = _text(body, "collection")
        clips = collection_clips(conn, path)
        if not clips:
            raise HTTPException(404, f"no clips in collection {path!r}")
        return clips
    clips = body.get("clips")
    if not isinstance(clips, list) or not clips or not all(type(c) is int for c in clips):
        raise HTTPException(400, 'give "clips": [ids] or "collection": "path"')
    return clips


def _apply_script(conn, request, body) -> Done:
    name = request.path_params["name"]
    clips = _target_clips(conn, _object(body))
    rows = conn.execute("SELECT * FROM modb.apply_edit_script(%s, %s)", [name, clips]).fetchall()
    results = [{"clip_id": c, "version": v, "n_frames": n, "snippets": k} for c, v, n, k in rows]
    return Done({"script": name, "results": results}, "edit script apply", name, {"clips": clips})


def _retarget(conn, request, body) -> Done:
    clip_id = _int(request, "ident")
    body = _object(body, "skeleton")
    skeleton, fps = body["skeleton"], body.get("fps")
    if type(skeleton) is not int:
        raise HTTPException(400, "skeleton: a skeleton's id")
    if fps is not None and (isinstance(fps, bool) or not isinstance(fps, (int, float))):
        raise HTTPException(400, "fps: a number")
    collection = _text(body, "collection", required=False)
    (made,) = conn.execute(
        "SELECT modb.retarget(%s, %s, %s, %s, %s)",
        [clip_id, skeleton, collection, fps, bool(body.get("mirror", False))],
    ).fetchone()
    version, n_frames, rate, path = conn.execute(
        "SELECT version, n_frames, fps, collection FROM modb.current_clips WHERE clip_id = %s",
        [made],
    ).fetchone()
    return Done(
        {
            "clip_id": made,
            "version": version,
            "n_frames": n_frames,
            "fps": rate,
            "collection": path,
        },
        "retarget",
        f"clip {clip_id}",
        {"skeleton": skeleton, "made": made},
        201,
    )


def routes(read_pool, tokens: Tokens, writer: Writer) -> list[Route]:
    def write(path: str, method: str, handler: Handler, with_body: bool = True) -> Route:
        return Route(path, write_endpoint(tokens, writer, handler, with_body), methods=[method])

    rows = [
        route
        for table in ("models", "graphs")
        for route in (
            write(f"/api/{table}", "POST", _create_row(table)),
            write(f"/api/{table}/{{ident}}", "PUT", _replace_row(table)),
            write(f"/api/{table}/{{ident}}", "DELETE", _delete_row(table), with_body=False),
        )
    ]
    return [
        write("/api/collections", "POST", _create_collection),
        write("/api/collections/{path:path}", "PATCH", _change_collection),
        write("/api/collections/{path:path}", "DELETE", _delete_collection, with_body=False),
        write("/api/clips/{ident}", "DELETE", _delete_clip, with_body=False),
        write(
            "/api/clips/{clip_id}/versions/{version}", "DELETE", _delete_version, with_body=False
        ),
        write("/api/clips/{clip_id}/versions/{version}/current", "POST", _restore_version, False),
        write("/api/clips/{ident}/retarget", "POST", _retarget),
        write("/api/edit-scripts/{name}", "PUT", _put_script),
        write("/api/edit-scripts/{name}", "DELETE", _delete_script, with_body=False),
        write("/api/edit-scripts/{name}/apply", "POST", _apply_script),
        Route(
            "/api/skeletons/{skeleton_id}/maps",
            maps_endpoint(read_pool, tokens, writer),
            methods=["GET", "PUT"],
        ),
        *rows,
    ]
