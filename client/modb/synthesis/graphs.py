"""Transition graphs (modb.build_transition_graph): build one, list them.

A graph keeps the snippets a chain can keep moving among; `modb synth --graph NAME` (or SET
modb.graph) makes select_next_snippet choose among them only. Building reads every snippet's
terminators (minutes for tens of thousands of snippets) and passes on the server's progress NOTICEs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import psycopg

NOTICE_PREFIX = "modb: "


@dataclass(frozen=True)
class GraphSummary:
    name: str
    profile: str
    collection: str | None
    snippets: int
    kept: int
    edges: int
    dead_ends: int
    # transitions stored, and no snippet of its scope added or removed since it was built
    current: bool


def build_graph(
    conn: psycopg.Connection,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    progress: Callable[[str], None] | None = None,
    min_turn_degrees: float = 45.0,
) -> GraphSummary:
    """Builds (or rebuilds) the graph `name` in one transaction and returns what it holds."""

    def on_notice(diag: psycopg.errors.Diagnostic) -> None:
        if progress and diag.message_primary and diag.message_primary.startswith(NOTICE_PREFIX):
            progress(diag.message_primary[len(NOTICE_PREFIX) :])

    conn.add_notice_handler(on_notice)
    try:
        with conn.transaction():
            conn.execute(
                "SELECT modb.build_transition_graph(%s, %s, %s, %s)",
                [name, profile, collection, min_turn_degrees],
            )
    finally:
        conn.remove_notice_handler(on_notice)
    return next(g for g in list_graphs(conn) if g.name == name)


def list_graphs(conn: psycopg.Connection) -> list[GraphSummary]:
    # Loads replace snippets (new ids): the graph's rows of removed snippets go with them (ON DELETE
    # CASCADE) and new snippets are not in it, so either count changing means it needs a rebuild. So
    # does
    # a graph built before 0.6.0, which stored no transitions (no transition_key) or no cost-to-go.
    rows = conn.execute(
        "SELECT g.name, g.data->>'profile', g.data->>'collection', (g.data->>'snippets')::int, "
        "       (g.data->>'kept')::int, (g.data->>'edges')::bigint, (g.data->>'dead_ends')::int, "
        "       g.data ?& '{transition_key,cost_to_go}' AND (SELECT count(*) FROM "
        "modb.graph_snippets gs WHERE gs.graph_id = g.id) = (g.data->>'kept')::int "
        "       AND (SELECT count(*) FROM modb.snippets s WHERE g.data->>'collection' IS NULL "
        "            OR s.collection_id = ANY (modb.collection_subtree(g.data->>'collection'))) "
        "           = (g.data->>'snippets')::int "
        "  FROM modb.graphs g WHERE g.kind = 'transitions' ORDER BY g.name"
    ).fetchall()
    return [GraphSummary(*row) for row in rows]


def ensure_graph(
    conn: psycopg.Connection,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> GraphSummary:
    """The graph `name`, built when it is missing or no longer current."""
    existing = next((g for g in list_graphs(conn) if g.name == name), None)
    if (
        existing
        and existing.current
        and existing.profile == profile
        and existing.collection == collection
    ):
        return existing
    return build_graph(conn, name, profile, collection, progress)


def describe(g: GraphSummary) -> str:
    scope = f"collection {g.collection}" if g.collection else "every collection"
    stale = (
        ""
        if g.current
        else (
            " STALE: snippets were loaded or removed since, or it was built before modb 0.6.0 "
            "stored transitions and a cost-to-go; rebuild it"
        )
    )
    return (
        f"{g.name}: {g.kept:,} of {g.snippets:,} snippets kept ({scope}, profile {g.profile}; "
        f"{g.edges:,} level-0 transitions, {g.dead_ends:,} snippets with none){stale}"
    )
