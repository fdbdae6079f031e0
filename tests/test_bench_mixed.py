"""`modb bench mixed` itself, briefly: one writer and one pgbench reader for 3 s on a fresh
database with three Bandai walks, and every count it holds against the database equal (audit rows
per action, clip versions, collections); each tally adds up; and the verdict fails on a 5xx or an
unequal count."""

from __future__ import annotations

import psycopg
from support.data import MOCAP, mocap

from modb.bench.mixed import Check, Mixed, run
from modb.bench.mixed_clients import Ledger
from modb.cli.bench import BenchCommands
from modb.database.cluster import ensure_writer_role


def test_a_short_mixed_run_counts_what_the_database_stored(fresh_db):
    mocap("bandai-2-dev", "data")
    mocap("bandai-1", "data")
    with psycopg.connect(fresh_db, autocommit=True) as conn:
        ensure_writer_role(conn)
    said: list[str] = []
    m = run(MOCAP, 1, 1, 0, 3, said.append, BenchCommands(), dsn=fresh_db, clips=3)

    assert m.checks and all(c.equal for c in m.checks), [c for c in m.checks if not c.equal]
    for (kind, action), t in m.ledger.tallies.items():
        answered = sum(t.classes.values())
        unanswered = m.ledger.extra["avatar goals unanswered at the end"] if kind == "avatar" else 0
        assert t.requests == answered + t.errors + unanswered, (kind, action, t)
    writes = {a: t for (k, a), t in m.ledger.tallies.items() if k == "writer"}
    # each kind of write was tried once at least, and something was stored
    assert set(writes) >= {"edit same clip", "resample", "retarget", "annotate", "upload"}
    assert sum(c.database for c in m.checks if c.what.startswith("audit rows")) > 0
    reads = m.ledger.tallies[("reader", "select_next_snippet")]
    assert reads.classes["ok"] > 0


def test_the_verdict_fails_on_a_server_error_or_an_unequal_count():
    def mixed(status: int, checks: list[Check]) -> Mixed:
        ledger = Ledger()
        ledger.answered("writer", "edit same clip", status, "")
        return Mixed(1, 0, 0, 1.0, 3, ledger, checks, [])

    assert mixed(200, [Check("audit rows", 1, 1)]).passed
    assert not mixed(500, [Check("audit rows", 1, 1)]).passed
    assert not mixed(200, [Check("audit rows", 1, 0)]).passed
