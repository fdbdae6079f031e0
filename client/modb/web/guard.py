"""Host and Origin checks for every request (HTTP and WebSocket) to the local web app.

The app serves the user's database to their own browser. Another web site open in that browser can
still send it requests, which are refused: by pointing its own DNS name at 127.0.0.1 (the Host
header then names that site) or by posting or opening a WebSocket from its page (the Origin header
then names that site). A request with more than one Host or more than one Origin header is refused
too: which of them counts would depend on who reads it (a proxy in front may check the first).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Receive, Scope, Send

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
WILDCARD_ADDRESSES = ("0.0.0.0", "::", "")  # bind to every interface; as a Host they name nothing


def is_loopback(host: str) -> bool:
    """Whether a --host address (bare, as given to bind) keeps the server on this machine."""
    return host in LOOPBACK_NAMES or f"[{host}]" in LOOPBACK_NAMES


def allowed_hosts(host: str, port: int, extra_names: Iterable[str] = ()) -> frozenset[str]:
    """Host header values that name this server: the loopback names, the address it binds to
    (unless a wildcard such as 0.0.0.0, which names nothing), and the names the user allowed (NAME,
    with this port, or NAME:PORT as a proxy in front would show it)."""
    given_port = {
        n.lower() for n in extra_names if re.fullmatch(r"[^:\[\]]+:[0-9]+|\[.+\]:[0-9]+", n)
    }
    names = {*LOOPBACK_NAMES, *(n for n in extra_names if n.lower() not in given_port)}
    if host not in WILDCARD_ADDRESSES:
        names.add(host if ":" not in host else f"[{host}]")
    # Browsers leave out the default port.
    bare = {name.lower() for name in names} if port == 80 else set()
    return frozenset(f"{name.lower()}:{port}" for name in names) | bare | given_port


class HostOriginGuard:
    """ASGI middleware: 403 for a Host this server does not answer to or an Origin not its own."""

    def __init__(self, app: ASGIApp, hosts: Iterable[str]) -> None:
        self.app = app
        self.hosts = frozenset(h.lower() for h in hosts)

    def refusal(self, scope: Scope) -> str | None:
        headers: dict[str, list[str]] = {}
        for k, v in scope["headers"]:
            headers.setdefault(k.decode("latin-1").lower(), []).append(v.decode("latin-1"))
        for name in ("host", "origin"):
            if len(headers.get(name, ())) > 1:
                return (
                    f"requests with {len(headers[name])} {name.capitalize()} headers are refused: "
                    "one at most is allowed"
                )
        host = headers.get("host", [""])[0].lower()
        if host not in self.hosts:
            return f"Host {host!r} is not this server: open it as http://{sorted(self.hosts)[0]}/"
        origin = headers.get("origin", [None])[0]
        page = urlsplit(origin) if origin is not None else None
        if page is not None and (
            page.scheme not in ("http", "https") or page.netloc.lower() not in self.hosts
        ):
            return (
                f"requests from the page of {origin!r} are refused: "
                "only this server's own pages may call it"
            )
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        reason = self.refusal(scope)
        if reason is None:
            await self.app(scope, receive, send)
        elif scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
        else:
            body = json.dumps({"error": reason}).encode()
            await send(
                {
                    "type": "http.response.start",
                    "status": 403,
                    "headers": [
                        (b"content-type", b"application/json"),
                        (b"content-length", str(len(body)).encode()),
                    ],
                }
            )
            await send({"type": "http.response.body", "body": body})
