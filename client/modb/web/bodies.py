"""A write's JSON body, read only after its token is checked and only up to a limit: a request
without a loader token costs the server nothing, and no body makes it hold more than the limit."""

from __future__ import annotations

import json
from typing import Any

from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.requests import Request

from modb.access.tokens import Grant

from .auth import Tokens


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


async def authorized_json(
    request: Request, tokens: Tokens, limit: int, with_body: bool = True
) -> tuple[Grant, Any]:
    """(the loader token's grant, the parsed body or None); 401/403, 411, 413 or 400 otherwise."""
    grant = await run_in_threadpool(tokens.writer, request)
    if not with_body:
        return grant, None
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
        return grant, json.loads(raw, parse_constant=_no_constant)
    except RecursionError:
        raise HTTPException(400, "the body is nested too deep") from None
    except (ValueError, UnicodeDecodeError) as e:
        raise HTTPException(400, f"the body is not JSON: {e}") from None
