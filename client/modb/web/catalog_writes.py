"""The REST interface's catalogue writes: collections (create, rename, move, delete), clips and
versions (delete, make an older version current), a skeleton's joint map and mirror pairs (with an
ETag), and `models` and `graphs` rows (create, replace, delete; a graph of models is replaced only
with the ETag it was read with, model_graph_routes). Like every write: a loader token, the writer
role's connection, one transaction with its modb.audit_log row, and errors as 400/404/409 with the
database's message."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg import sql
from psycopg.types.json import Jsonb
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse
from starlette.routing import Route

from modb.access import audit
from modb.clips import collection_clips
from modb.editing import catalog
from modb.editing.script_notes import version_notes

from . import model_graph_routes
from .api import BadRequest, NotFound
from . import body_models as bodies
from .auth import Tokens
from .bodies import authorized_json, parse
from .body_models import MAX_ID
from .writes import Writer

MAX_DOCUMENT_BYTES = 24 << 20  # a model's data (16 MB at most) with its meta, as JSON
WRITE_TIMEOUT_S = "30s"  # a JSON write's statements, as a read's


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


def _int(request: Request, name: str, what: str) -> int:
    """A whole number from the path (an id, a version)."""
    text = request.path_params[name]
    if not text.isascii() or not text.isdigit() or int(text) > MAX_ID:
        raise BadRequest(f"{what}: a whole number from 0 to {MAX_ID}, got {text!r:.40}")
    return int(text)


TABLES = {"clip": "clips", "skeleton": "skeletons", "model": "models", "graph": "graphs"}


def _existing(conn: psycopg.Connection, what: str, ident: int) -> int:
    """`ident`, or 404 naming the object that is not there (as the reads do)."""
    table = sql.Identifier("modb", TABLES[what])
    query = sql.SQL("SELECT 1 FROM {} WHERE id = %s").format(table)
    if conn.execute(query, [ident]).fetchone() is None:
        raise NotFound(f"no {what} with id {ident}")
    return ident


def _current_clips(conn: psycopg.Connection, clips: list[int]) -> list[int]:
    """The clips, each with a version of its own, or 404 naming the first that has none."""
    have = {
        c
        for (c,) in conn.execute(
            "SELECT clip_id FROM modb.current_clips WHERE clip_id = ANY(%s)", [clips]
        )
    }
    missing = [c for c in clips if c not in have]
    if missing:
        raise NotFound(f"no clip with id {missing[0]} (with a version of its own)")
    return clips


def write_endpoint(
    tokens: Tokens,
    writer: Writer,
    handler: Handler,
    body: Any = None,
    frames: bool = False,
    if_match: str | None = None,
):
    """An endpoint running `handler` as one audited transaction of the writer role, on the body
    checked against its model `body` (body_models; none read without one): the handler gets the
    fields given. The model is the endpoint's `request_body`, which /api/openapi.json publishes.
    `if_match`: what the ETag names, asked for (428) before the body is checked. `frames`: the
    handler makes clip versions (edits, retargeting), after which the connection is closed, not
    pooled again: a server process keeps part of the memory of the frames it computed (about 2 kB
    per frame, outside PostgreSQL's and Python's accounting, BENCHMARKS.md), so each such write gets
    a fresh one and the writers' memory stays bounded."""

    def run(request: Request, grant, given: Any) -> JSONResponse:
        if if_match and not request.headers.get("if-match"):
            raise HTTPException(428, f"send If-Match with the ETag of {if_match} you read")
        fields = None if body is None else parse(body, given)  # before any work
        # A database error leaves the transaction rolled back; the app answers it (database_errors)
        request.state.grant = grant  # whose token: a job's submitter
        with writer.pool().connection() as conn:
            try:
                with conn.transaction():
                    # as on reads: a request is not a job (uploads keep the writer's longer cap)
                    conn.execute("SELECT set_config('statement_timeout', %s, true)",
                                 [WRITE_TIMEOUT_S])  # fmt: skip
                    done = handler(conn, request, fields)
                    audit.record(conn, grant.name, done.action, done.obj, done.detail)
            finally:
                if frames:
                    conn.close()  # the pool drops a closed connection and opens another
        return JSONResponse(done.body, status_code=done.status, headers=done.headers)

    async def endpoint(request: Request) -> JSONResponse:
        grant, given = await authorized_json(request, tokens, MAX_DOCUMENT_BYTES, body is not None)
        return await run_in_threadpool(run, request, grant, given)

    endpoint.request_body = body
    return endpoint


# Collections


def _create_collection(conn, request, body) -> Done:
    """A new collection (and the levels above it); 409 when it exists (nothing audited)."""
    path = body["path"]
    # two creates of one path queue here, so the second finds the first's and is the 409
    conn.execute(
        "SELECT pg_advisory_xact_lock(hashtext('modb.collections: a create'), hashtext(%s))",
        [path],
    )
    if catalog.find_collection(conn, path) is not None:
        raise Conflict(f"collection {path!r} already exists")
    found, shown = catalog.create_collection(conn, path)
    return Done({"id": found, "path": shown}, "collection create", shown, {}, 201)


def _change_collection(conn, request, body) -> Done:
    path = request.path_params["path"]
    shown = path
    if "parent" in body:
        shown = catalog.move_collection(conn, shown, body["parent"])
    if "name" in body:
        shown = catalog.rename_collection(conn, shown, body["name"])
    return Done({"path": shown}, "collection change", path, {"now": shown})


def _delete_collection(conn, request, body) -> Done:
    path = request.path_params["path"]
    given = request.query_params.get("with_clips", "false").lower()
    if given not in ("1", "true", "yes", "0", "false", "no"):
        raise BadRequest(f"with_clips: true or false, got {given!r:.40}")
    with_clips = given in ("1", "true", "yes")
    clips = catalog.delete_collection(conn, path, with_clips)
    return Done({"deleted": path, "clips": clips}, "collection delete", path, {"clips": clips})


class Conflict(HTTPException):
    def __init__(self, detail: str) -> None:
        super().__init__(409, detail)


# Clips and versions


def _delete_clip(conn, request, body) -> Done:
    clip_id = _existing(conn, "clip", _int(request, "ident", "clip id"))
    versions = catalog.delete_clip(conn, clip_id)
    return Done(
        {"deleted": clip_id, "versions": versions},
        "clip delete",
        f"clip {clip_id}",
        {"versions": versions},
    )


def _version_path(conn, request) -> tuple[int, int]:
    clip_id = _existing(conn, "clip", _int(request, "clip_id", "clip id"))
    return clip_id, _int(request, "version", "version")


def _delete_version(conn, request, body) -> Done:
    clip_id, version = _version_path(conn, request)
    r = catalog.delete_version(conn, clip_id, version)
    return Done(
        {"deleted": version, "current_version": r.version, "snippets": r.snippets},
        "version delete",
        f"clip {clip_id} version {version}",
        {"current_version": r.version},
    )


def _restore_version(conn, request, body) -> Done:
    clip_id, version = _version_path(conn, request)
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
    put = write_endpoint(tokens, writer, _put_maps, bodies.SkeletonMaps, if_match="the maps")

    def get(request: Request) -> JSONResponse:
        tokens.reader(request)
        skeleton_id = _int(request, "skeleton_id", "skeleton id")
        with read_pool.connection() as conn:
            try:
                maps = catalog.read_maps(conn, skeleton_id)
            except catalog.SkeletonNotFound:
                raise NotFound(f"no skeleton with id {skeleton_id}") from None
        return JSONResponse(_maps_body(maps), headers={"ETag": maps.etag})

    async def endpoint(request: Request) -> JSONResponse:
        if request.method == "GET":
            return await run_in_threadpool(get, request)
        return await put(request)

    endpoint.request_body = put.request_body
    return endpoint


def _put_maps(conn, request, body) -> Done:
    skeleton_id = _int(request, "skeleton_id", "skeleton id")
    if_match = request.headers["if-match"]  # (write_endpoint asked for it)
    if body.get("skeleton_id", skeleton_id) != skeleton_id:
        raise BadRequest(f"skeleton_id: {body['skeleton_id']}, but the path names {skeleton_id}")
    if not body["joint_map"]:
        raise BadRequest(
            "joint_map: empty; snippets are cut from the standard joints it maps "
            "(GET the maps for the current one)"
        )
    try:
        maps, recut = catalog.write_maps(
            conn, skeleton_id, body["joint_map"], body["mirror_pairs"], if_match,
            body.get("joint_axes"),
        )  # fmt: skip
    except catalog.SkeletonNotFound:
        raise NotFound(f"no skeleton with id {skeleton_id}") from None
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


def _row_fields(conn, fields: dict[str, Any], table: str) -> dict[str, Any]:
    if fields.get("kind") in BUILT_KINDS and table == "graphs":
        raise BadRequest("transition graphs are built: `modb graph build NAME`")
    if fields.get("skeleton_id") is not None:
        _existing(conn, "skeleton", fields["skeleton_id"])
    for key in ("data", "meta"):
        if key in fields:
            fields[key] = Jsonb(fields[key])
    return fields


def _taken(conn, table: str, name: str, kind: str) -> None:
    """409 when a row of that name and kind exists (the table's unique key)."""
    query = sql.SQL("SELECT id FROM {} WHERE name = %s AND kind = %s").format(
        sql.Identifier("modb", table)
    )
    row = conn.execute(query, [name, kind]).fetchone()
    if row is not None:
        what = f"a {table[:-1]} named {name!r} of kind {kind!r}"
        raise Conflict(f"{what} already exists: id {row[0]}")


def _create_row(table: str):
    def handler(conn, request, body) -> Done:
        fields = _row_fields(conn, body, table)
        _taken(conn, table, fields["name"], fields["kind"])
        if table == "graphs":  # a graph's name is also its row in modb.graph_names (83_graphs.sql)
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
        headers = None
        if table == "graphs" and fields["kind"] == model_graph_routes.KIND:  # checked, kept
            headers = {"ETag": model_graph_routes.current_etag(conn, made)}
        return Done(
            {"id": made, "name": fields["name"], "kind": fields["kind"]},
            f"{table[:-1]} create",
            f"{table[:-1]} {made}",
            {"name": fields["name"], "kind": fields["kind"]},
            201,
            headers,
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
        raise NotFound(f"no {table[:-1]} with id {ident}")
    return row


def _replace_row(table: str):
    def handler(conn, request, body) -> Done:
        ident = _int(request, "ident", f"{table[:-1]} id")
        fields = _row_fields(conn, body, table)
        name, kind = _row(conn, table, ident)
        if table == "graphs" and (kind in BUILT_KINDS or {"name", "kind"} & fields.keys()):
            raise BadRequest(
                "a graph's name and kind stay; a transition graph is rebuilt, not replaced "
                "(`modb graph build NAME`)"
            )
        models_graph = table == "graphs" and kind == model_graph_routes.KIND
        if models_graph:  # 428 or 409 unless it is the graph the editor read
            model_graph_routes.check_if_match(conn, request, ident)
        if table == "models" and fields.keys() - {"meta"}:
            return _new_model_version(conn, ident, name, kind, fields)
        if {"name", "kind"} & fields.keys():
            new = (fields.get("name", name), fields.get("kind", kind))
            if new != (name, kind):
                _taken(conn, table, *new)
        assignments = sql.SQL(", ").join(
            sql.SQL("{} = %s").format(sql.Identifier(k)) for k in fields
        )
        conn.execute(
            sql.SQL("UPDATE {} SET {} WHERE id = %s").format(
                sql.Identifier("modb", table), assignments
            ),
            [*fields.values(), ident],
        )  # a graph of models the database finds broken is refused here (check_violation: 400)
        body: dict[str, Any] = {"id": ident, "replaced": sorted(fields)}
        headers = None
        if models_graph:
            body["etag"] = model_graph_routes.current_etag(conn, ident)
            headers = {"ETag": body["etag"]}
        return Done(
            body,
            f"{table[:-1]} replace",
            f"{table[:-1]} {ident}",
            {"fields": sorted(fields), "name": name, "kind": kind},
            headers=headers,
        )

    return handler


def _new_model_version(conn, ident: int, name: str, kind: str, fields: dict[str, Any]) -> Done:
    """A model's data is never overwritten (modb.models_version_rules): a replace stores the row
    with the fields changed as the model's next version, the old kept."""
    if fields.get("name", name) != name or fields.get("kind", kind) != kind:
        raise BadRequest("a model's name and kind stay: a new name is a new model (POST)")
    changed = {k: v for k, v in fields.items() if k not in ("name", "kind")}
    kept = [c for c in ("skeleton_id", "collection_id", "data", "meta") if c not in changed]
    # new data keeps the notes, not the acceleration tree drawn from the old data's mixture
    kept_values = [
        sql.SQL("meta - 'tree'") if c == "meta" and "data" in changed else sql.Identifier(c)
        for c in kept
    ]
    query = sql.SQL(
        "INSERT INTO modb.models (name, kind, {columns}) SELECT name, kind, {values} "
        "FROM modb.models WHERE id = %s RETURNING id, version"
    ).format(
        columns=sql.SQL(", ").join(map(sql.Identifier, [*changed, *kept])),
        values=sql.SQL(", ").join([sql.Placeholder()] * len(changed) + kept_values),
    )
    made, version = conn.execute(query, [*changed.values(), ident]).fetchone()
    return Done(
        {"id": made, "version": version, "replaced": sorted(fields), "previous": ident},
        "model new version",
        f"model {made}",
        {"fields": sorted(fields), "name": name, "kind": kind, "version": version},
        201,
        headers={"Location": f"/api/models/{made}"},
    )


def _delete_row(table: str):
    def handler(conn, request, body) -> Done:
        ident = _int(request, "ident", f"{table[:-1]} id")
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


def _script_name(request: Request) -> str:
    return parse(bodies.TEXT, request.path_params["name"], "edit script name")


def _put_script(conn, request, body) -> Done:
    name = _script_name(request)
    commands = body["commands"]  # (the kernel's own check: body_models.EDIT_SCRIPT)
    (made,) = conn.execute(
        "INSERT INTO modb.edit_scripts (name, commands, comment) VALUES (%s, %s, %s) "
        "ON CONFLICT (name) DO UPDATE SET commands = EXCLUDED.commands, "
        "comment = EXCLUDED.comment RETURNING xmax = 0",
        [name, Jsonb(commands), body.get("comment")],
    ).fetchone()
    return Done(
        {"name": name, "commands": len(commands)},
        "edit script save",
        name,
        {"commands": commands},
        201 if made else 200,
    )


def _delete_script(conn, request, body) -> Done:
    name = request.path_params["name"]
    if conn.execute("DELETE FROM modb.edit_scripts WHERE name = %s", [name]).rowcount == 0:
        raise NotFound(f"no edit script {name!r}")
    return Done({"deleted": name}, "edit script delete", name, {})


def _target_clips(conn, body: dict[str, Any]) -> list[int]:
    """The clips named (each once: body_models.Targets), or those of the collection; 404 for one
    that is not there."""
    if "collection" in body:
        path = body["collection"]
        if catalog.find_collection(conn, path) is None:
            raise NotFound(f"no collection {path!r}")
        clips = collection_clips(conn, path)
        if not clips:
            raise NotFound(f"no clips in collection {path!r}")
        return list(dict.fromkeys(clips))
    return _current_clips(conn, body["clips"])


def apply_script(conn, request, body) -> Done:
    """At once (one transaction); job_routes.apply_script makes a whole collection's a job."""
    name = request.path_params["name"]
    clips = _target_clips(conn, body)
    if conn.execute("SELECT 1 FROM modb.edit_scripts WHERE name = %s", [name]).fetchone() is None:
        raise NotFound(f"no edit script {name!r}")
    rows = conn.execute("SELECT * FROM modb.apply_edit_script(%s, %s)", [name, clips]).fetchall()
    # notes: the ik and rotate commands' (an ik target's distance when it is out of reach)
    results = [
        {"clip_id": c, "version": v, "n_frames": n, "snippets": k,
         "notes": version_notes(conn, c, v)}
        for c, v, n, k in rows
    ]  # fmt: skip
    return Done({"script": name, "results": results}, "edit script apply", name, {"clips": clips})


def _retarget(conn, request, body) -> Done:
    clip_id = _int(request, "ident", "clip id")
    _current_clips(conn, [clip_id])
    skeleton = _existing(conn, "skeleton", body["skeleton"])
    (made,) = conn.execute(
        "SELECT modb.retarget(%s, %s, %s, %s, %s)",
        [clip_id, skeleton, body.get("collection"), body.get("fps"), body.get("mirror", False)],
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


def _steps(conn, request, body) -> Done:
    """The clip's steps found and written as automatic segments of its current version."""
    clip_id = _int(request, "ident", "clip id")
    _current_clips(conn, [clip_id])
    rows = conn.execute(
        "SELECT version, name, start_frame, end_frame, keyframes FROM modb.annotate_steps(%s)",
        [clip_id],
    ).fetchall()
    steps = [{"name": n, "start": s, "end": e, "keyframes": k} for _, n, s, e, k in rows]
    return Done(
        {"clip_id": clip_id, "version": rows[0][0] if rows else None, "steps": steps},
        "annotate steps", f"clip {clip_id}", {"steps": len(steps)},
    )  # fmt: skip


def _action(conn, request, body) -> Done:
    """The clip's action found and written as automatic segments of its current version."""
    clip_id = _int(request, "ident", "clip id")
    _current_clips(conn, [clip_id])
    rows = conn.execute(
        "SELECT version, name, start_frame, end_frame, keyframes, hands, kind "
        "FROM modb.annotate_action(%s, %s)", [clip_id, body["action"]],
    ).fetchall()  # fmt: skip
    segments = [{"name": n, "start": s, "end": e, "keyframes": k, "hands": h, "kind": kind}
                for _, n, s, e, k, h, kind in rows]  # fmt: skip
    return Done(
        {"clip_id": clip_id, "version": rows[0][0] if rows else None, "action": body["action"],
         "segments": segments},
        "annotate action", f"clip {clip_id}", {"action": body["action"]},
    )  # fmt: skip


def routes(read_pool, tokens: Tokens, writer: Writer) -> list[Route]:
    def write(path: str, method: str, handler: Handler, body: Any = None, frames=False) -> Route:
        endpoint = write_endpoint(tokens, writer, handler, body, frames)
        return Route(path, endpoint, methods=[method])

    rows = [
        route
        for table in ("models", "graphs")
        for route in (
            write(f"/api/{table}", "POST", _create_row(table), bodies.NewRow),
            write(f"/api/{table}/{{ident}}", "PUT", _replace_row(table), bodies.RowChange),
            write(f"/api/{table}/{{ident}}", "DELETE", _delete_row(table)),
        )
    ]
    return [
        write("/api/collections", "POST", _create_collection, bodies.NewCollection),
        write("/api/collections/{path:path}", "PATCH", _change_collection, bodies.CollectionChange),
        write("/api/collections/{path:path}", "DELETE", _delete_collection),
        write("/api/clips/{ident}", "DELETE", _delete_clip),
        write("/api/clips/{clip_id}/versions/{version}", "DELETE", _delete_version),
        write("/api/clips/{clip_id}/versions/{version}/current", "POST", _restore_version),
        write("/api/clips/{ident}/retarget", "POST", _retarget, bodies.Retarget, frames=True),
        write("/api/clips/{ident}/steps", "POST", _steps, frames=True),
        write("/api/clips/{ident}/action", "POST", _action, bodies.Action, frames=True),
        write("/api/edit-scripts/{name}", "PUT", _put_script, bodies.EditScript),
        write("/api/edit-scripts/{name}", "DELETE", _delete_script),
        Route(
            "/api/skeletons/{skeleton_id}/maps",
            maps_endpoint(read_pool, tokens, writer),
            methods=["GET", "PUT"],
        ),
        *rows,
    ]
