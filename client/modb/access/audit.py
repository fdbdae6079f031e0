"""The audit log: one modb.audit_log row per write through the REST interface, in the write's own
transaction, so a write and its record are stored together or not at all."""

from __future__ import annotations

from typing import Any

import psycopg
from psycopg.types.json import Jsonb


def record(
    conn: psycopg.Connection, token_name: str, action: str, obj: str, detail: dict[str, Any]
) -> None:
    conn.execute(
        "INSERT INTO modb.audit_log (token_name, action, object, detail) VALUES (%s, %s, %s, %s)",
        [token_name, action, obj, Jsonb(detail)],
    )
