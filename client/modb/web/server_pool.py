"""`modb serve`'s connection pools, which tell a database that went away (`modb db stop`, a
server restarted or moved) from one that is only busy: a request waits a moment for a pooled
connection, then asks the server directly; a server that does not answer is a 503 at once saying
where it was looked for (host, port, database; never a password), instead of every request waiting
out the pool's whole wait. The pool keeps reconnecting in the background and, since it gives up on
a failed reconnection quickly, the next request starts a fresh one: the server comes back by
itself when the database does."""

from __future__ import annotations

import psycopg
from psycopg.conninfo import conninfo_to_dict
from psycopg_pool import ConnectionPool, PoolTimeout

FIRST_WAIT_S = 1.0  # a pooled connection within this, or the server is asked directly
PROBE_TIMEOUT_S = 2  # libpq's connect_timeout (2 s at least) for that question
RECONNECT_TIMEOUT_S = 10.0  # a background reconnection that fails this long gives up


class Unreachable(RuntimeError):
    """The database did not answer: a 503 with Retry-After."""


def where(conninfo: str) -> str:
    """Where the database is looked for, without a password: 'host=... port=... dbname=...'."""
    params = conninfo_to_dict(conninfo)
    shown = ("host", "hostaddr", "port", "dbname")
    return " ".join(f"{k}={params[k]}" for k in shown if params.get(k))


def probe(conninfo: str) -> None:
    """Unreachable unless the server takes a new connection now."""
    try:
        psycopg.connect(conninfo, connect_timeout=PROBE_TIMEOUT_S).close()
    except psycopg.OperationalError as e:
        reason = str(e).strip().split("\n", 1)[0] or type(e).__name__  # the next: libpq's advice
        raise Unreachable(
            f"the database is unreachable ({where(conninfo) or 'libpq defaults'}): {reason:.200}; "
            "is it running? (`modb db start` starts the embedded one)"
        ) from None


class ServerPool(ConnectionPool):
    """A ConnectionPool whose waits for a connection first make sure the server is there."""

    def __init__(self, conninfo: str, **kwargs) -> None:
        kwargs.setdefault("reconnect_timeout", RECONNECT_TIMEOUT_S)
        kwargs.setdefault("check", ConnectionPool.check_connection)  # a dead connection is dropped
        super().__init__(conninfo, **kwargs)
        self.probe_conninfo = conninfo

    def getconn(self, timeout: float | None = None):
        wait = self.timeout if timeout is None else timeout
        if wait <= FIRST_WAIT_S:
            return super().getconn(wait)
        try:
            return super().getconn(FIRST_WAIT_S)
        except PoolTimeout:
            probe(self.probe_conninfo)  # every connection may be busy; or the server is gone
        return super().getconn(wait - FIRST_WAIT_S)
