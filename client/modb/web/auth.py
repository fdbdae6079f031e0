"""Bearer tokens on the REST interface: every write needs a live loader token; reads need a token
only with `modb serve --require-token`. A token comes in the Authorization header and nowhere else
(never a cookie a page on another origin could ride, never a URL a log would keep)."""

from __future__ import annotations

from psycopg_pool import ConnectionPool
from starlette.exceptions import HTTPException
from starlette.requests import Request

from modb.access.tokens import Grant, grant

CHALLENGE = {"WWW-Authenticate": 'Bearer realm="modb"'}


class Unauthorized(HTTPException):
    def __init__(self, detail: str) -> None:
        super().__init__(401, detail, headers=CHALLENGE)


class Forbidden(HTTPException):
    def __init__(self, detail: str) -> None:
        super().__init__(403, detail)


def presented_token(request: Request) -> str | None:
    values = request.headers.getlist("authorization")
    if not values:
        return None
    scheme, _, token = values[0].partition(" ")
    if len(values) > 1 or scheme.lower() != "bearer" or not token.strip():
        raise Unauthorized("the Authorization header takes one 'Bearer <token>'")
    return token.strip()


class Tokens:
    """Checks the request's token against modb.token_grant on a pooled (read) connection."""

    def __init__(self, pool: ConnectionPool, require_for_reads: bool) -> None:
        self.pool = pool
        self.require_for_reads = require_for_reads

    def _grant(self, request: Request) -> Grant:
        return self.check(presented_token(request))

    def check(self, token: str | None) -> Grant:
        """The grant of a live token, else 401 (none, unknown or revoked)."""
        if token is None:
            raise Unauthorized(
                "this needs an access token: send 'Authorization: Bearer <token>' "
                "(`modb token create NAME --role loader` makes one)"
            )
        with self.pool.connection() as conn:
            found = grant(conn, token)
        if found is None:
            raise Unauthorized("the access token is unknown or revoked")
        return found

    def writer(self, request: Request) -> Grant:
        """The grant of a loader token, else 401 (none, unknown, revoked) or 403 (a reader's)."""
        found = self._grant(request)
        if not found.may_write:
            raise Forbidden(f"token {found.name!r} is a reader's: writes need a loader token")
        return found

    def reader(self, request: Request) -> Grant | None:
        """With --require-token, the grant of any live token (else 401); otherwise None."""
        return self._grant(request) if self.require_for_reads else None
