"""Access tokens: made, listed and revoked by `modb token`, checked by `modb serve` on every write.

A token is "modb_" and 43 characters of 32 random bytes (URL-safe base64). It is shown once, when
made; the database keeps only its sha256 (modb.access_tokens), and the server asks
modb.token_grant(sha256) for the name and role of a live token, so no role but the table's owner
reads the table.
"""

from __future__ import annotations

import hashlib
import re
import secrets
from dataclasses import dataclass
from datetime import datetime

import psycopg

PREFIX = "modb_"
ROLES = ("loader", "reader")  # loader: reads and writes; reader: reads
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,62}$")  # modb.access_tokens' check
# What a well-formed token looks like, so a malformed one is refused before any database work.
TOKEN = re.compile(r"^modb_[A-Za-z0-9_-]{43}$")


class TokenError(ValueError):
    pass


@dataclass(frozen=True)
class Grant:
    """A live token's name and role."""

    name: str
    role: str

    @property
    def may_write(self) -> bool:
        return self.role == "loader"


@dataclass(frozen=True)
class TokenRow:
    name: str
    role: str
    created_at: datetime
    created_by: str
    revoked_at: datetime | None


def digest(token: str) -> bytes:
    return hashlib.sha256(token.encode("ascii", "replace")).digest()


def create(conn: psycopg.Connection, name: str, role: str) -> str:
    """A new token (returned once) named `name` with `role`."""
    if not NAME.match(name):
        raise TokenError(
            "a token name is 1 to 63 letters, digits or . _ @ - (starting with a letter or "
            f"digit), got {name!r:.80}"
        )
    if role not in ROLES:
        raise TokenError(f"a token's role is one of {', '.join(ROLES)}, got {role!r:.40}")
    token = PREFIX + secrets.token_urlsafe(32)
    try:
        with conn.transaction():
            conn.execute(
                "INSERT INTO modb.access_tokens (name, role, token_sha256) VALUES (%s, %s, %s)",
                [name, role, digest(token)],
            )
    except psycopg.errors.UniqueViolation:
        raise TokenError(
            f"a token named {name!r} exists (`modb token list`; a revoked one keeps its name for "
            f"the audit log): choose another name"
        ) from None
    return token


def list_tokens(conn: psycopg.Connection) -> list[TokenRow]:
    rows = conn.execute(
        "SELECT name, role, created_at, created_by, revoked_at FROM modb.access_tokens "
        "ORDER BY created_at, name"
    ).fetchall()
    return [TokenRow(*row) for row in rows]


def revoke(conn: psycopg.Connection, name: str) -> bool:
    """Revokes the live token `name`; False when there is none. A revoked token keeps its row (the
    audit log names it) and its name: a new token needs a new name."""
    with conn.transaction():
        row = conn.execute(
            "UPDATE modb.access_tokens SET revoked_at = now() "
            "WHERE name = %s AND revoked_at IS NULL RETURNING 1",
            [name],
        ).fetchone()
    return row is not None


def grant(conn: psycopg.Connection, token: str) -> Grant | None:
    """The name and role of a live token; None for an unknown, revoked or malformed one."""
    if not TOKEN.match(token):
        return None
    row = conn.execute("SELECT name, role FROM modb.token_grant(%s)", [digest(token)]).fetchone()
    return Grant(*row) if row else None
