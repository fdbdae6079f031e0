"""Where a read-only session runs: on one of the primary's hot standbys, spread by the number of
sessions each serves, or on the primary when no standby answers.

libpq 15 has no `load_balance_hosts`, so the choice is made here. A node that fails to connect,
or whose connection breaks, is left out for DOWN_SECONDS. A standby must have replayed what the
session needs: a new session, the primary's WAL as it was when the session opened (so a standby
serves a load once it has replayed it, and the web view's lists, read on the primary, never offer
what the session's node lacks); a session that moves (its node stopped), the snippet it continues
from. One that has not is waited for up to REPLAY_WAIT_SECONDS (in all, over every node tried),
else passed over and left out for DOWN_SECONDS.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import psycopg
from psycopg.conninfo import make_conninfo

from .cluster import Cluster
from .connection import connect
from .replicas import Replicas

DOWN_SECONDS = 5.0
DISCOVER_SECONDS = 5.0  # how often the embedded database's standbys are looked up again
REPLAY_WAIT_SECONDS = 0.25  # in all, within a moving walk's half-second budget
REPLAY_POLL_SECONDS = 0.02
# A node across a network that stops answering is given up in seconds, not TCP's minutes (unix
# sockets ignore these: a stopped server there fails at once).
CONNECTION_OPTIONS = {
    "connect_timeout": 2,
    "keepalives": 1,
    "keepalives_idle": 5,
    "keepalives_interval": 1,
    "keepalives_count": 3,
    "tcp_user_timeout": 5000,
}


@dataclass
class Node:
    name: str
    dsn: str
    standby: bool
    sessions: int = 0
    down_until: float = 0.0


class NoNode(RuntimeError):
    """No node could serve the session, and why."""


class NotReplayed(RuntimeError):
    """A standby lacks what the session needs (it lags, or its replay is paused)."""


class ReadNodes:
    def __init__(
        self,
        primary: str,
        standbys: Iterable[tuple[str, str]] = (),
        discover: Callable[[], Iterable[tuple[str, str]]] | None = None,
    ) -> None:
        self._lock = threading.Lock()
        self.primary = Node("primary", primary, standby=False)
        self.standbys = [Node(name, dsn, standby=True) for name, dsn in standbys]
        self._discover = discover
        self._discovered_at = time.monotonic()

    @classmethod
    def embedded(cls, primary: str) -> ReadNodes:
        """The embedded database's primary and its standbys (`modb db replica add`), looked up
        again every DISCOVER_SECONDS: one added while serving takes new sessions, one removed no
        more; one that is stopped is tried again after DOWN_SECONDS."""

        def standbys() -> list[tuple[str, str]]:
            return [(r.name, r.node.dsn()) for r in Replicas(Cluster.default()).all()]

        return cls(primary, standbys(), discover=standbys)

    def refresh(self) -> None:
        """The standbys as `discover` finds them now, at most every DISCOVER_SECONDS (a node
        kept keeps its count of sessions)."""
        if self._discover is None or time.monotonic() - self._discovered_at < DISCOVER_SECONDS:
            return
        self._discovered_at = time.monotonic()
        try:
            found = dict(self._discover())
        except OSError:  # the folder being changed under us: the last list stands
            return
        with self._lock:
            known = {n.name: n for n in self.standbys}
            self.standbys = [
                known[name] if name in known and known[name].dsn == dsn else Node(name, dsn, True)
                for name, dsn in found.items()
            ]

    def _take(self, passed: set[str]) -> Node | None:
        """The next node to try, counted at once (sessions opening together spread too):
        standbys up, fewest sessions first; then the primary; then standbys down (they may be
        back). None when every node was tried."""
        now = time.monotonic()
        with self._lock:
            left = [n for n in [*self.standbys, self.primary] if n.name not in passed]
            if not left:
                return None
            node = min(
                left,
                key=lambda n: (
                    n.down_until > now,
                    not n.standby,
                    n.sessions if n.down_until <= now else n.down_until,
                ),
            )
            node.sessions += 1
            return node

    def open(
        self, needed_snippet: int | None = None, avoid: Iterable[str] = ()
    ) -> tuple[Node, psycopg.Connection]:
        """A node for a new session (or one moving, which continues from `needed_snippet`) and an
        autocommit connection to it; the node counts the session until release()."""
        self.refresh()
        passed, why = set(avoid), []
        deadline = time.monotonic() + REPLAY_WAIT_SECONDS
        lsn, lsn_read = None, False  # the primary's, read when a standby is first tried
        while (node := self._take(passed)) is not None:
            passed.add(node.name)
            conn = None
            try:
                conn = connect(make_conninfo(node.dsn, **CONNECTION_OPTIONS))
                if not node.standby:
                    return node, conn
                if needed_snippet is None and not lsn_read:
                    lsn, lsn_read = self._primary_lsn(), True
                while (lacking := _lacking(conn, needed_snippet, lsn)) is not None:
                    if time.monotonic() >= deadline:
                        raise NotReplayed(f"has not replayed {lacking} yet")
                    time.sleep(REPLAY_POLL_SECONDS)
                return node, conn
            except (psycopg.Error, RuntimeError) as e:
                self.mark_down(node)
                why.append(f"{node.name}: {e}")
            if conn is not None:
                conn.close()
            self.release(node)
        raise NoNode("no database node can serve this session: " + "; ".join(why))

    def _primary_lsn(self) -> str | None:
        """Where the primary's WAL is now; None when the primary does not answer (then a standby
        serves what it has: the primary is gone, or being promoted)."""
        try:
            with connect(make_conninfo(self.primary.dsn, **CONNECTION_OPTIONS)) as conn:
                # flushed: what a standby can have received (the write position may be ahead)
                return str(conn.execute("SELECT pg_current_wal_flush_lsn()").fetchone()[0])
        except (psycopg.Error, RuntimeError):
            return None

    def release(self, node: Node) -> None:
        with self._lock:
            node.sessions = max(0, node.sessions - 1)

    def mark_down(self, node: Node) -> None:
        with self._lock:
            node.down_until = time.monotonic() + DOWN_SECONDS

    def describe(self) -> str:
        if not self.standbys:
            return "avatar sessions on the primary (no standbys)"
        return "avatar sessions on standbys " + ", ".join(n.name for n in self.standbys)


def _lacking(conn: psycopg.Connection, snippet: int | None, lsn: str | None) -> str | None:
    """What a standby has not replayed yet of what a session needs (the snippet a moving session
    continues from, else the primary's WAL up to `lsn`), or None."""
    if snippet is not None:
        has = conn.execute("SELECT 1 FROM modb.snippets WHERE id = %s", [snippet]).fetchone()
        return None if has else f"snippet {snippet}"
    if lsn is None:
        return None
    replayed = conn.execute(
        "SELECT coalesce(pg_last_wal_replay_lsn() >= %s::pg_lsn, true)", [lsn]
    ).fetchone()[0]
    return None if replayed else f"the primary's WAL up to {lsn}"
