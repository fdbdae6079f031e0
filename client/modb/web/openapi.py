"""The OpenAPI 3.1 description of `modb serve`'s JSON interface, served at /api/openapi.json:
what each operation is (its summary, parameters and answers) from the table here, its request body
from the model its route checks the body with (body_models.py, the route's `request_body`), as
pydantic's JSON Schema under components/schemas. No body is written here. tests/test_rest_writes.py
checks that it names every route the app has; tests/test_rest_contract.py that each body is
checked as it is published."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from pydantic import TypeAdapter
from starlette.requests import Request
from starlette.responses import JSONResponse

from modb.version import __version__

from .bodies import json_schema
from .body_models import PATH, PublishedSchema


ERROR = {"type": "object", "properties": {"error": {"type": "string"}}, "required": ["error"]}
ANY = {"type": "object"}


def _id(name: str, about: str) -> dict[str, Any]:
    return {"name": name, "in": "path", "required": True, "description": about,
            "schema": {"type": "integer", "minimum": 0}}  # fmt: skip


def _query(name: str, about: str, schema: dict[str, Any]) -> dict[str, Any]:
    return {"name": name, "in": "query", "required": False, "description": about, "schema": schema}


def _responses(ok: str, *errors: int, body: dict[str, Any] = ANY) -> dict[str, Any]:
    why = {
        400: "bad input: the message names the field and what it takes (checked before any work)",
        401: "no token, or an unknown or revoked one",
        403: "a reader's token on a write",
        404: "no such object (the message names it: 'no clip with id 7')",
        409: "it already exists, or it changed since it was read (for meta and maps the body or "
        "headers hold the current ETag)",
        411: "no Content-Length",
        413: "larger than the server's upload limit",
        428: "no If-Match",
        503: "try again (Retry-After): busy, a write met another on the same rows, the database "
        "unreachable (the message says where), or writes are off on this server (it says why)",
    }
    out: dict[str, Any] = {
        "200": {"description": ok, "content": {"application/json": {"schema": body}}}
    }
    for status in errors:
        out[str(status)] = {
            "description": why[status],
            "content": {"application/json": {"schema": ERROR}},
        }
    return out


READ = "Open on loopback; with `modb serve --require-token`, any live token."
WRITE = "Needs a loader token (`modb token create NAME --role loader`)."
CLIP = _id("ident", "clip id")


def _read(summary: str, *params: dict[str, Any], media: str = "application/json") -> dict:
    op: dict[str, Any] = {
        "summary": summary,
        "description": READ,
        "parameters": list(params),
        "responses": _responses("the answer", 400, 401, 404, 503),
    }
    if media != "application/json":
        op["responses"]["200"] = {"description": "the file", "content": {media: {}}}
    return {"get": op}


_WRITE_ERRORS = (400, 401, 403, 404, 409, 503)


def _write(
    summary: str,
    *params: dict[str, Any],
    ok: str = "done",
    errors: tuple[int, ...] = _WRITE_ERRORS,
    about: str = "",
) -> dict:
    op: dict[str, Any] = {
        "summary": summary,
        "description": f"{WRITE} {about}".strip(),
        "security": [{"token": []}],
        "parameters": list(params),
        "responses": _responses(ok, *errors),
    }
    return op


IF_MATCH = {"name": "If-Match", "in": "header", "required": True, "schema": {"type": "string"}}
GRAPH_IF_MATCH = {
    **IF_MATCH,
    "required": False,
    "description": "a graph of models: the ETag its GET gave (required for one)",
}
MODEL_GRAPHS = (
    "A graph of models (kind models) is replaced only with If-Match naming the ETag of the graph "
    "read (428 without; 409 with the current ETag when it changed since). The database checks it "
    "(modb.model_graph_problem): a broken one is refused, 400 with its reason."
)
COLLECTION_PATH = {"name": "path", "in": "path", "required": True, "schema": {"type": "string"},
                   "description": 'a path like "bandai/walks", URL-encoded'}  # fmt: skip


def catalog_writes() -> dict[str, dict[str, Any]]:
    """The catalogue writes (catalog_writes.py), by path and method."""
    version_params = [_id("clip_id", "clip id"), _id("version", "clip version")]
    out: dict[str, dict[str, Any]] = {
        "/api/collections": {
            "post": _write(
                "create a collection (and the levels above it)",
                ok="its id and path (201); 409 when it exists",
            )
        },
        "/api/collections/{path}": {
            "patch": _write(
                "rename and/or move a collection",
                COLLECTION_PATH,
                ok="its new path",
                about='"parent": "" moves it to the top.',
            ),
            "delete": _write(
                "delete a collection and those below it",
                COLLECTION_PATH,
                _query("with_clips", "delete the clips in it too", {"type": "boolean"}),
                ok="how many clips went",
                about="Without with_clips it must hold no clips (409).",
            ),
        },
        "/api/clips/{ident}": {
            "delete": _write(
                "delete a clip: every version, its snippets (graphs over them become stale)",
                CLIP,
                ok="how many versions went",
            )
        },
        "/api/clips/{clip_id}/versions/{version}": {
            "delete": _write(
                "delete one version (not the only one); the one before becomes current and is cut",
                *version_params,
                ok="the version now current and its snippets",
            )
        },
        "/api/clips/{clip_id}/versions/{version}/current": {
            "post": _write(
                "make an older version current again (a new version with its motion and meta)",
                *version_params,
                ok="the new version's number and snippets",
            )
        },
        "/api/skeletons/{skeleton_id}/maps": {
            "get": {
                "summary": "a skeleton's joint map and mirror pairs, and their ETag",
                "description": READ,
                "parameters": [_id("skeleton_id", "skeleton id")],
                "responses": _responses("the maps; the ETag header names them", 401, 404),
            },
            "put": _write(
                "replace a skeleton's joint map and mirror pairs",
                _id("skeleton_id", "skeleton id"),
                IF_MATCH,
                ok="the stored maps, and how many clips were cut again",
                errors=(400, 401, 403, 404, 409, 428, 503),
                about="Every clip on the skeleton is cut into snippets again.",
            ),
        },
    }
    script = {"name": "name", "in": "path", "required": True, "schema": {"type": "string"},
              "description": "the edit script's name"}  # fmt: skip
    out["/api/clips/{ident}/retarget"] = {"post": _write(
        "retarget the clip onto another skeleton, as a new clip linked to it", CLIP,
        ok="the new clip (201)")}  # fmt: skip
    out["/api/edit-scripts/{name}"] = {
        "put": _write("store an edit script (replacing one of that name)", script,
                      ok="stored (201 when new)"),
        "delete": _write("delete an edit script", script, ok="its name"),
    }  # fmt: skip
    out["/api/edit-scripts/{name}/apply"] = {"post": _write(
        "apply an edit script: a new version of each clip named (one transaction); to a whole "
        "collection, a job (202) where the database has job tables", script,
        ok="each clip's new version, or the queued job (202, Location: /api/jobs/ID)")}  # fmt: skip
    out["/api/clips/{ident}/steps"] = {"post": _write(
        "find the clip's steps from its feet's contacts: left_step and right_step segments of its "
        "current version, marked automatic (replacing those of a run before)", CLIP,
        ok="the steps written")}  # fmt: skip
    collection_path = {"name": "path", "in": "path", "required": True, "schema": {"type": "string"},
                       "description": "the collection's path"}  # fmt: skip
    out["/api/collections/{path}/steps"] = {"post": _write(
        "find the steps of every clip of the collection, as a job", collection_path,
        ok="the queued job (202, Location: /api/jobs/ID)")}  # fmt: skip
    out["/api/clips/{ident}/action"] = {"post": _write(
        "find the clip's action done standing (body {\"action\": NAME}): a segment NAME with "
        "its keyframes, hands and kind (reach or repeat), and idle for a standing lead-in and "
        "lead-out, marked automatic (replacing those of a run before for that action)", CLIP,
        ok="the segments written")}  # fmt: skip
    out["/api/collections/{path}/action"] = {"post": _write(
        "find the action (body {\"action\": NAME}) of every clip of the collection, as a job",
        collection_path, ok="the queued job (202, Location: /api/jobs/ID)")}  # fmt: skip
    out["/api/processed-data"] = {
        "get": {
            "summary": "processed-data rows (aligned examples of motion primitives) without their "
            "frames; stale says why a row is stale",
            "description": READ,
            "parameters": [
                {"name": n, "in": "query", "required": False, "schema": {"type": "string"}}
                for n in ("collection", "primitive")
            ],
            "responses": _responses("the rows", 401),
        },
        "post": _write(
            "align a primitive's examples in a collection in time (a job where the database has "
            "job tables)",
            ok="the queued job (202), or the counts (200)",
        ),
    }
    out["/api/processed-data/{ident}"] = _read(
        "one processed-data row whole: aligned frames, time function, sections, settings",
        _id("ident", "processed-data row id"),
    )
    out["/api/collections/{path}/retarget"] = {"post": _write(
        "retarget every clip of the collection onto another skeleton, as a job",
        collection_path,
        ok="the queued job (202, Location: /api/jobs/ID)")}  # fmt: skip
    out.update(_motion_models())
    for table in ("models", "graphs"):
        one = _id("ident", f"{table[:-1]} id")
        note = " (not transition graphs: `modb graph build`)" if table == "graphs" else ""
        out[f"/api/{table}"] = {
            "post": _write(
                f"create a {table[:-1]} row{note}",
                ok="its id (201)" + ("; a graph of models' ETag" if table == "graphs" else ""),
                about="The database checks a graph of models (400 with why it is broken)."
                if table == "graphs"
                else "",
            )
        }
        graph = table == "graphs"
        out[f"/api/{table}/{{ident}}"] = {
            "put": _write(
                f"replace fields of a {table[:-1]} row{note}",
                *((one, GRAPH_IF_MATCH) if graph else (one,)),
                ok="the fields replaced" + ("; a graph of models' new ETag" if graph else ""),
                errors=(400, 401, 403, 404, 409, 428, 503) if graph else _WRITE_ERRORS,
                about=MODEL_GRAPHS if graph else "",
            ),
            "delete": _write(f"delete a {table[:-1]} row", one, ok="its id"),
        }
    return out


def _motion_models() -> dict[str, Any]:
    name = {"name": "name", "in": "path", "required": True, "schema": {"type": "string"},
            "description": "the model's name"}  # fmt: skip
    version = _query("version", "the version (default: the latest)", {"type": "integer"})
    n = _query("n", "how many (1 to 50; 10)", {"type": "integer", "minimum": 1, "maximum": 50})
    return {
        "/api/motion-models": _read(
            "statistical motion models, every version, with why one is stale",
            _query("collection", "built from this collection (path)", {"type": "string"}),
        ),
        "/api/motion-models/{name}": _read(
            "one model's version in brief: examples, components, variance kept, mixture, tree",
            name, version,
        ),
        "/api/motion-models/{name}/samples": _read(
            "samples drawn from the model (modb.sample_motion): frames and world positions",
            name, n, _query("seed", "the same seed, the same samples (0)", {"type": "integer"}),
            version,
        ),
        "/api/motion-models/{name}/examples": _read(
            "examples the model was built from, placed and played as its samples are",
            name, n, version,
        ),
        "/api/motion-models/{name}/build": {"post": _write(
            "build a model of a primitive's aligned examples as the next version of NAME (a job "
            "where the database has job tables; aligns first when the processed data is missing "
            "or stale)", name,
            ok="the queued job (202, Location: /api/jobs/ID), or the model made (201)")},
    }  # fmt: skip


def operations() -> dict[str, Any]:
    """Every operation, by path and method, without its JSON request body."""
    version_params = [_id("clip_id", "clip id"), _id("version", "clip version")]
    paths: dict[str, Any] = {
        "/api/collections": _read("every collection, with its clips' count"),
        "/api/clips": _read(
            "clips (newest versions)",
            _query("collection", "only this collection's (id)", {"type": "integer"}),
            _query("tag", "only those tagged so", {"type": "string"}),
            _query("annotation", "only those with a segment so named", {"type": "string"}),
        ),
        "/api/clips/{ident}": _read("one clip: versions, skeleton, meta", CLIP),
        "/api/clips/{ident}/frames": _read(
            "a version's frames as world positions",
            CLIP,
            _query("version", "clip version (default: newest)", {"type": "integer"}),
            _query("start", "first frame", {"type": "integer"}),
            _query("count", "frames (at most 20,000)", {"type": "integer"}),
        ),
        "/api/clips/{ident}/download": _read(
            "a version as a file",
            CLIP,
            _query("version", "clip version (default: newest)", {"type": "integer"}),
            _query("format", "bvh, glb or gltf", {"enum": ["bvh", "glb", "gltf"]}),
            media="application/octet-stream",
        ),
        "/api/skeletons": _read("every skeleton"),
        "/api/skeletons/{ident}": _read("one skeleton", _id("ident", "skeleton id")),
        "/api/skeletons/{ident}/character.glb": _read(
            "a skinned capsule character of the skeleton",
            _id("ident", "skeleton id"),
            media="model/gltf-binary",
        ),
        "/api/models": _read("every model"),
        "/api/models/{ident}": _read("one model", _id("ident", "model id")),
        "/api/graphs": _read(
            "every graph; graphs of models with how many nodes and transitions they have",
            _query("kind", "only graphs of this kind (models, transitions...)", {"type": "string"}),
        ),
        "/api/graphs/{ident}": _read(
            "one graph; a graph of models (kind models) with its ETag (If-Match of a PUT)",
            _id("ident", "graph id"),
        ),
        "/api/graphs/{ident}/synthesis": _read(
            "the strip a graph of models walks (modb.synthesize_from_models): its goals, then each "
            "action walked to and performed meeting its target; frames and the report",
            _id("ident", "graph id"),
            _query("to", "a goal X,Z (metres; repeatable, in order with the actions)",
                   {"type": "string"}),
            _query("action", "NAME:X,Y,Z[:SECONDS]: an action of the graph and its hand's target "
                   "(a wave: the point it faces, how long); repeatable", {"type": "string"}),
            _query("seconds", "the strip's length (20; at most 600)", {"type": "number"}),
            _query("seed", "the same seed, the same walk (0)", {"type": "integer"}),
            _query("arrival_radius", "a goal is reached this near (0.5 m)", {"type": "number"}),
        ),
        "/api/profiles": _read("the match profiles"),
        "/api/edit-scripts": _read("the stored edit scripts"),
        "/api/jobs": {
            **_read("the newest 200 jobs (modb.jobs): state, submitter, progress, log, result"),
            "post": _write(
                "queue a job (kind build_graph: arguments name, profile, collection, "
                "min_turn_degrees, as `modb graph build`; retarget: clips or from_collection, "
                "skeleton, collection, fps, mirrored; apply_edit_script: clips or from_collection, "
                "script; split_by_annotation: clips or from_collection, annotation, collection; "
                "annotate_steps: clips or from_collection; annotate_action: clips or "
                "from_collection, action; align: primitive, collection), "
                "after the jobs `after` are done; a worker runs it",
                ok="the queued job (202, Location: /api/jobs/ID)",
            ),  # fmt: skip
        },
        "/api/jobs/{ident}": _read("one job", _id("ident", "job id")),
        "/api/jobs/{ident}/cancel": {
            "post": _write(
                "cancel a queued job; a running one stops at its next step, nothing half-made kept",
                _id("ident", "job id"),
                ok="the job",
            )
        },
        "/api/clips/{clip_id}/versions/{version}/meta": {
            "get": {
                "summary": "a version's meta (annotations, tags) and its ETag",
                "description": READ,
                "parameters": version_params,
                "responses": _responses("the meta; the ETag header names it", 401, 404),
            },
            "put": {
                "summary": "replace a version's meta",
                "description": WRITE + " Send If-Match with the ETag of the meta you read: a "
                "write over a meta that changed since is refused (409), so no edit is lost.",
                "security": [{"token": []}],
                "parameters": [
                    *version_params,
                    {
                        "name": "If-Match",
                        "in": "header",
                        "required": True,
                        "schema": {"type": "string"},
                    },  # fmt: skip
                ],
                "responses": _responses(
                    "the stored meta; the ETag header names it", 400, 401, 403, 404, 409, 428, 503
                ),
            },
        },
        "/api/uploads": {
            "post": {
                "summary": "load BVH files, or AMC files with their ASF, as `modb load` does",
                "description": WRITE + " One transaction per file; an unchanged file stores "
                "nothing, a changed one a new version. 200 when a file was stored or unchanged, "
                "else 400; each file's result either way.",
                "security": [{"token": []}],
                "requestBody": {
                    "required": True,
                    "content": {
                        "multipart/form-data": {
                            "schema": {
                                "type": "object",
                                "properties": {
                                    "collection": {**json_schema(PATH), "default": "uploads"},
                                    "file": {
                                        "type": "array",
                                        "items": {"type": "string", "format": "binary"},
                                    },
                                },
                            }
                        }
                    },
                },
                "responses": _responses("each file's result", 400, 401, 403, 411, 413, 503),
            }
        },
        "/api/openapi.json": {
            "get": {"summary": "this description", "responses": _responses("OpenAPI 3.1")}
        },
    }
    paths["/api/clips/{ident}/edit-preview"] = {"post": {
        "summary": "an edit script's result on the clip's current version, not stored: the frames "
        "it changes (as /frames gives them: start, count) and each command's note (an ik target "
        "out of reach: the nearest point and its distance); what applying the script stores",
        "description": READ,
        "parameters": [CLIP],
        "responses": _responses("the frames changed and the notes", 400, 401, 404, 411, 413, 503),
    }}  # fmt: skip
    for path, methods in catalog_writes().items():
        paths.setdefault(path, {}).update(methods)
    return paths


def _documented(path: str) -> str:
    """A route's path as documented: "/api/collections/{path:path}" is "/api/collections/{path}"."""
    return re.sub(r"\{(\w+):\w+\}", r"{\1}", path)


def schema(routes: list) -> dict[str, Any]:
    """The document for the app's `routes`: each route whose endpoint checks a body against a model
    (its `request_body`, for its methods but GET) gets that model's JSON Schema as its body."""
    paths = operations()
    bodies: dict[tuple[str, str], Any] = {}
    for route in routes:
        model = getattr(getattr(route, "endpoint", None), "request_body", None)
        for method in sorted(set(getattr(route, "methods", None) or ()) - {"GET", "HEAD"}):
            if model is not None:
                bodies[_documented(route.path), method.lower()] = model
    inputs = [(key, "validation", TypeAdapter(model)) for key, model in bodies.items()]
    published, definitions = TypeAdapter.json_schemas(
        inputs, ref_template="#/components/schemas/{model}", schema_generator=PublishedSchema
    )
    for (path, method), _ in bodies.items():
        if method not in paths.get(path, {}):
            raise LookupError(f"{method.upper()} {path} takes a body but is not described here")
        paths[path][method]["requestBody"] = {
            "required": True,
            "content": {"application/json": {"schema": published[(path, method), "validation"]}},
        }
    return {
        "openapi": "3.1.0",
        "info": {
            "title": "MoDB for PostgreSQL",
            "version": __version__,
            "description": "The motion database's REST interface (`modb serve`).",
        },
        "components": {
            "schemas": definitions.get("$defs", {}),
            "securitySchemes": {
                "token": {
                    "type": "http",
                    "scheme": "bearer",
                    "description": "`modb token create NAME --role loader|reader`",
                }
            },
        },
        "paths": paths,
    }


def endpoint(routes: list) -> Callable[[Request], JSONResponse]:
    """GET /api/openapi.json: the document for `routes` (made at the first request, when the list
    holds every route)."""
    made: list[dict[str, Any]] = []

    def answer(request: Request) -> JSONResponse:
        if not made:
            made.append(schema(routes))
        return JSONResponse(made[0])

    return answer
