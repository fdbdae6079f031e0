"""Transition graphs (modb.build_transition_graph): build one, list them.

A graph keeps the snippets a chain can keep moving among; `modb synth --graph NAME` (or SET modb.graph)
makes select_next_snippet choose among them only. Building reads every snippet's terminators, so it
takes minutes for tens of thousands of snippets; the server's progress NOTICEs are passed on.
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


def build_graph(conn: psycopg.Connection, name: str, profile: str = "default", collection: str | None = None,
                progress: Callable[[str], None] | None = None) -> GraphSummary:
    """Builds (or rebuilds) the graph `name` in one transaction and returns what it holds."""
    def on_notice(diag: psycopg.errors.Diagnostic) -> None:
        if progress and diag.message_primary and diag.message_primary.startswith(NOTICE_PREFIX):
            progress(diag.message_primary[len(NOTICE_PREFIX):])

    conn.add_notice_handler(on_notice)
    try:
        with conn.transaction():
            conn.execute("SELECT modb.build_transition_graph(%s, %s, %s)", [name, profile, collection])
    finally:
        conn.remove_notice_handler(on_notice)
    return next(g for g in list_graphs(conn) if g.name == name)


def list_graphs(conn: psycopg.Connection) -> list[GraphSummary]:
    rows = conn.execute(
        "SELECT name, data->>'profile', data->>'collection', (data->>'snippets')::int, (data->>'kept')::int, "
        "(data->>'edges')::bigint, (data->>'dead_ends')::int FROM modb.graphs WHERE kind = 'transitions' "
        "ORDER BY name").fetchall()
    return [GraphSummary(*row) for row in rows]


def describe(g: GraphSummary) -> str:
    scope = f"collection {g.collection}" if g.collection else "every collection"
    return (f"{g.name}: {g.kept:,} of {g.snippets:,} snippets kept ({scope}, profile {g.profile}; "
            f"{g.edges:,} level-0 transitions, {g.dead_ends:,} snippets with none)")
