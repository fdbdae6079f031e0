"""Opening a connection that knows modb's types, with errors that say what to do."""
from __future__ import annotations

import psycopg

from . import pgarray


class NotInstalledError(RuntimeError):
    pass


def connect(conninfo: str) -> psycopg.Connection:
    conn = psycopg.connect(conninfo, autocommit=True)
    pgarray.register(conn)
    row = conn.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'").fetchone()
    if row is None:
        db = conn.info.dbname
        conn.close()
        raise NotInstalledError(
            f"database {db!r} has no modb extension: run `CREATE EXTENSION modb CASCADE` there as a superuser "
            f"(after `make setup` installed it into the server)")
    return conn
