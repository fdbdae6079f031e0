"""Opening a connection that knows modb's types, with errors that say what to do."""

from __future__ import annotations

import psycopg

from . import pgarray
from .dsn import resolve


# Since 0.10.0 select_next_snippets (C) plans nothing per call and never JIT-compiles; these
# settings still spare the SQL a chain runs around it (select_next_snippet_world's wrapper, the
# bench's baselines) planning at each call and JIT.
SELECTION_SETTINGS = {"plan_cache_mode": "force_generic_plan", "jit": "off"}


def configure_for_selection(conn: psycopg.Connection) -> None:
    """Sets SELECTION_SETTINGS for a session that calls select_next_snippet repeatedly."""
    conn.execute(
        "SELECT set_config(name, value, false) FROM unnest(%s::text[], %s::text[]) AS s(name, "
        "value)",
        [list(SELECTION_SETTINGS), list(SELECTION_SETTINGS.values())],
    )


class NotInstalledError(RuntimeError):
    pass


def connect(conninfo: str | None = None) -> psycopg.Connection:
    """An autocommit connection that reads and writes modb's arrays as numpy. Without a conninfo,
    the database the `modb` command would use (MODB_DSN, libpq's environment, the embedded one)."""
    if conninfo is None:
        conninfo, _ = resolve(None)
    conn = psycopg.connect(conninfo, autocommit=True)
    pgarray.register(conn)
    row = conn.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'").fetchone()
    if row is None:
        db = conn.info.dbname
        conn.close()
        raise NotInstalledError(
            f"database {db!r} has no modb extension: run `CREATE EXTENSION modb CASCADE` there as "
            f"a superuser (after `make setup` installed it into the server)"
        )
    return conn
