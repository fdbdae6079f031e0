"""A transition graph built in this process (a job worker's, on any machine): its inputs read by the
database's functions, computed by the kernel as modb.build_transition_graph would in the server
(modb_kernel.graph_build), stored in one transaction by modb.store_transition_graph."""

from __future__ import annotations

from collections.abc import Callable

import psycopg
from psycopg.rows import dict_row
from psycopg.types.json import Jsonb

from modb_kernel import graph_build

PLAN = """
SELECT to_jsonb(p) - 'box_half_width' AS shown, modb.transition_key(p) AS transition_key, p.*
  FROM modb.match_plan(%s) p
"""


class GraphJobError(ValueError):
    pass


def can_build_here(conn: psycopg.Connection) -> bool:
    """Whether the extension has the functions a build outside the server needs (0.19.0 on)."""
    return conn.execute(
        "SELECT to_regprocedure('modb.transition_graph_inputs(text, text, float8)') IS NOT NULL"
    ).fetchone()[0]


def build_here(
    conn: psycopg.Connection,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    min_turn_degrees: float = 45.0,
    notice: Callable[[str], None] = lambda text: None,
    advance: Callable[[int, int], None] | None = None,
) -> int:
    """Builds (or rebuilds) the graph `name`; returns its modb.graphs id."""
    if not can_build_here(conn):
        raise GraphJobError(
            "the database's modb extension is older than 0.19.0, which a worker needs: run "
            "ALTER EXTENSION modb UPDATE there (`modb db start` does it on the embedded database)"
        )
    # One snapshot for the snippets and their terminators; nothing held open while the kernel works.
    with conn.transaction(), conn.cursor(row_factory=dict_row) as cur:
        conn.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ, READ ONLY")
        try:
            snippets = cur.execute(
                "SELECT * FROM modb.transition_graph_inputs(%s, %s, %s)",
                [name, collection, min_turn_degrees],
            ).fetchall()
            plan = cur.execute(PLAN, [profile]).fetchone()
        except psycopg.Error as e:
            hint = e.diag.message_hint
            raise GraphJobError(
                f"{e.diag.message_primary}" + (f" ({hint})" if hint else "")
            ) from None
        notice(f'transition graph "{name}": reading the terminators of {len(snippets)} snippets')
        ids = sorted(
            {r["begin_terminator"] for r in snippets} | {r["end_terminator"] for r in snippets}
        )
        terminators = cur.execute(
            "SELECT * FROM modb.transition_graph_terminators(%s)", [ids]
        ).fetchall()
    try:
        built = graph_build.build(
            name, snippets, terminators, plan, plan["shown"], plan["transition_key"], profile,
            collection, min_turn_degrees, notice=notice, advance=advance,
        )  # fmt: skip
    except graph_build.GraphBuildError as e:
        raise GraphJobError(f"{e} ({e.hint})") from None
    del snippets, terminators
    with conn.transaction():
        return conn.execute(
            "SELECT modb.store_transition_graph(%s, %s, %s::bigint[], %s::bigint[], %s::bigint[], "
            "%s::real[], %s)",
            [
                name,
                Jsonb(built.data),
                built.kept,
                built.from_ids,
                built.to_ids,
                built.costs.ravel().tolist(),
                built.width,
            ],  # fmt: skip
        ).fetchone()[0]
