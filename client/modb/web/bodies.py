"""A write's JSON body, read only after its token is checked and only up to a limit (a request
without a loader token costs the server nothing, and no body makes it hold more than the limit),
then checked against its model (body_models.py) before any work. A refusal is a 400 naming the
field and what it takes, in the words of the schema /api/openapi.json publishes: "mirror: true or
false, got 'no'", "clips[0]: a clip id (a whole number from 1 to ...), got 1.5", "the body: unknown
field 'mirorr'; it takes ...", 'the body: "skeleton" is missing: ...'."""

from __future__ import annotations

import json
import re
from typing import Any

from pydantic import BaseModel, TypeAdapter, ValidationError
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request

from modb.access.tokens import Grant

from .auth import Tokens
from .body_models import LINES, PARENT_PATTERN, PATH_PATTERN, PublishedSchema


class Invalid(ValueError):
    """A body (or a name in the path) that is not what the endpoint takes: a 400 with this
    message."""


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


async def authorized_json(
    request: Request, tokens: Tokens, limit: int, with_body: bool = True
) -> tuple[Grant, Any]:
    """(the loader token's grant, the parsed body or None); 401/403, 411, 413 or 400 otherwise."""
    grant = await run_in_threadpool(tokens.writer, request)
    if not with_body:
        await _no_body(request)
        return grant, None
    return grant, await json_body(request, limit)


async def json_body(request: Request, limit: int) -> Any:
    """The request's body parsed as JSON, read only up to `limit` bytes; 411, 413 or 400 otherwise
    (a read that takes a body, such as the edit preview, calls it after checking its token)."""
    length = request.headers.get("content-length")
    if length is None or not length.isdigit():
        raise HTTPException(411, "send Content-Length")
    if int(length) > limit:
        raise HTTPException(413, f"the body is larger than this server's limit of {limit:,} bytes")
    raw = bytearray()
    async for chunk in request.stream():
        raw += chunk
        if len(raw) > limit:  # a Content-Length that lied
            raise HTTPException(
                413, f"the body is larger than this server's limit of {limit:,} bytes"
            )
    try:
        return json.loads(raw, parse_constant=_no_constant)
    except RecursionError:
        raise HTTPException(400, "the body is nested too deep") from None
    except (ValueError, UnicodeDecodeError) as e:
        raise HTTPException(400, f"the body is not JSON: {e}") from None


NO_BODY_LIMIT = 1024


async def _no_body(request: Request) -> None:
    """A write that takes no body refuses one that says something (an empty body, `{}` or `null`
    are nothing): a field sent there would be ignored, as an unknown field is refused elsewhere."""
    raw = bytearray()
    async for chunk in request.stream():
        raw += chunk
        if len(raw) > NO_BODY_LIMIT:
            break
    text = raw.decode("utf-8", "replace").strip()
    if text and text not in ("{}", "null"):
        shown = text if len(text) <= 80 else text[:77] + "..."
        raise HTTPException(
            400, f"the body: {request.method} {request.url.path} takes none (got {shown})"
        )


# --- checking a body against its model ------------------------------------------------------------

_ADAPTERS: dict[int, tuple[Any, TypeAdapter, dict[str, Any]]] = {}


def _adapter(kind: Any) -> tuple[TypeAdapter, dict[str, Any]]:
    """The type's validator and its published JSON Schema (its $defs inside), made once."""
    if id(kind) not in _ADAPTERS:
        adapter = TypeAdapter(kind)
        _ADAPTERS[id(kind)] = (kind, adapter, adapter.json_schema(schema_generator=PublishedSchema))
    _, adapter, schema = _ADAPTERS[id(kind)]
    return adapter, schema


def json_schema(kind: Any) -> dict[str, Any]:
    return _adapter(kind)[1]


def parse(kind: Any, value: Any, where: str = "the body") -> Any:
    """`value` checked against `kind` (strict: no "5" for 5): a model's fields as given (those
    left out left out), or the value; Invalid naming the field (`where` for the whole) else."""
    adapter, schema = _adapter(kind)
    try:
        checked = adapter.validate_python(value, strict=True)
    except ValidationError as e:
        raise Invalid(refusal(schema, e.errors(include_url=False), value, where)) from None
    return checked.model_dump(exclude_unset=True) if isinstance(checked, BaseModel) else checked


def _shown(value: Any) -> str:
    return f"{value!r:.60}"


class _At:
    """The schema at a place in a value, the place in words ("joint_axes.joints.head.twist[0]"),
    and the fields on the way (a discriminated union's tag is no field)."""

    def __init__(self, root: dict[str, Any], loc: tuple, where: str) -> None:
        self.defs = root.get("$defs", {})
        node, shown, self.fields = self._open(root), "", []
        for k, key in enumerate(loc):
            tags = node.get("discriminator", {}).get("mapping", {})
            if isinstance(key, str) and key in tags:
                node = self._open({"$ref": tags[key]})
                continue
            node = self._open(self._inside(node))
            if key == "[key]":  # (an object's name, the key before it, is refused)
                continue
            self.fields.append(key)
            if loc[k + 1 : k + 2] == ("[key]",):
                node, shown = node.get("propertyNames", {}), f"{shown} key"
            elif isinstance(key, int):
                node, shown = self._open(node.get("items", {})), f"{shown}[{key}]"
            else:
                known = node.get("properties", {})
                node = self._open(known.get(key, node.get("additionalProperties") or {}))
                shown = f"{shown}.{key}" if shown else str(key)
        self.node, self.shown = node, shown or where

    def _open(self, node: dict[str, Any]) -> dict[str, Any]:
        while "$ref" in node:  # its own keywords (a field's description) over the definition's
            target = self.defs[node["$ref"].rsplit("/", 1)[1]]
            node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
        return node

    def _inside(self, node: dict[str, Any]) -> dict[str, Any]:
        """A nullable value's schema when not null."""
        for branch in node.get("anyOf", ()):
            if branch.get("type") != "null":
                return self._open(branch)
        return node


def expects(node: dict[str, Any]) -> str:
    """What a schema takes, in words: its description, or its object's fields."""
    if "properties" in node and node.get("type") == "object":
        required = node.get("required", ())
        return "an object with " + ", ".join(
            f'"{k}"' + ("" if k in required else " (optional)") for k in node["properties"]
        )
    if "discriminator" in node:
        name = node["discriminator"]["propertyName"]
        return f'an object with "{name}" (one of {_listed(_tags(node))}) and that kind\'s fields'
    return node.get("description", "anything")


def _listed(names) -> str:
    return ", ".join(f'"{n}"' for n in names)


def _tags(node: dict[str, Any]) -> list[str]:
    """A discriminated union's tags, in the order of its branches."""
    mapping = node["discriminator"]["mapping"]
    order = [branch.get("$ref") for branch in node.get("oneOf", ())]
    return sorted(mapping, key=lambda tag: order.index(mapping[tag]))


_CONTROLS = {LINES: re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")}
_ANY_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def _pattern_problem(node: dict[str, Any], value: str) -> str | None:
    bad = _CONTROLS.get(node.get("pattern"), _ANY_CONTROL).search(value)
    if bad:
        return f"holds the control character {bad.group()!r}"
    if node.get("pattern") in (PATH_PATTERN, PARENT_PATTERN):
        for k, segment in enumerate(value.split("/"), 1):
            if segment.strip() in ("", ".", ".."):
                return (f"segment {k} of {value!r:.60} is {segment!r:.20}: each segment is a name "
                        "(not empty, '.' or '..')")  # fmt: skip
    return None


def refusal(schema: dict[str, Any], errors: list[dict[str, Any]], value: Any, where: str) -> str:
    """The first problem, as the old checks put them first: an unknown field, then a missing one,
    then the fields in the order given."""
    given = list(value) if isinstance(value, dict) else []

    def rank(error: dict[str, Any]) -> tuple[int, int]:
        fields = _At(schema, error["loc"], where).fields
        if len(fields) == 1 and error["type"] in ("extra_forbidden", "missing"):
            return (0 if error["type"] == "extra_forbidden" else 1), 0
        return 2, given.index(fields[0]) if fields and fields[0] in given else len(given)

    error = min(errors, key=rank)
    loc, kind, got = error["loc"], error["type"], error.get("input")
    at = _At(schema, loc, where)
    if kind in ("extra_forbidden", "missing"):
        parent = _At(schema, loc[:-1], where)
        owner = parent._inside(parent.node)
        if kind == "missing":
            return f'{parent.shown}: "{loc[-1]}" is missing: {expects(at.node)}'
        takes = _listed(owner.get("properties", {})) or "no other field"
        return f"{parent.shown}: unknown field {loc[-1]!r:.60}; it takes {takes}"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        name = at.node["discriminator"]["propertyName"]
        tags = _listed(_tags(at.node))
        if kind == "union_tag_not_found":
            return f'{at.shown}: "{name}" is missing: one of {tags}'
        field = name if at.shown == where else f"{at.shown}.{name}"
        return f"{field}: one of {tags}, got {_shown(got.get(name))}"
    if kind in ("min_properties", "one_of", "edit_script"):
        return f"{at.shown}: {error['msg']}"
    if kind == "string_pattern_mismatch" and isinstance(got, str):
        problem = _pattern_problem(at._inside(at.node), got)
        if problem:
            return f"{at.shown}: {problem}"
    node = at.node if got is None else at._inside(at.node)  # not null: what it is when not
    return f"{at.shown}: {expects(node)}, got {_shown(got)}"
