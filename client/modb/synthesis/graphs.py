"""Transition graphs (modb.build_transition_graph): build one, list them.

A graph keeps the snippets a chain can keep moving among; `modb synth --graph NAME` (or SET
modb.graph) makes select_next_snippet choose among them only. Building reads every snippet's
terminators (minutes for tens of thousands of snippets) and passes on the server's progress NOTICEs.
"""

from __future__ import annotations

import time
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
    rows = conn.execute(
        "SELECT g.name, g.data->>'profile', g.data->>'collection', (g.data->>'snippets')::int, "
        "       (g.data->>'kept')::int, (g.data->>'edges')::bigint, (g.data->>'dead_ends')::int, "
        "       modb.graph_is_current(g.id) "
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


# Building compares every snippet's end with the starts near it, so its time grows about with the
# square of the scope; how long it takes depends on the host and its load (measured builds of one
# scope differed threefold), so no number is promised. A first synthesis builds graphs of up to
# AUTO_BUILD_SNIPPETS itself and names the command for larger ones.
AUTO_BUILD_SNIPPETS = 60_000
GROWTH = "its time grows with the square of the snippets"


def auto_graph_name(profile: str, collection: str | None) -> str:
    return f"auto {profile} {collection or '(every collection)'}"


def build_default_graph(
    conn: psycopg.Connection,
    profile: str,
    collection: str | None,
    say: Callable[[str], None],
    progress: Callable[[str], None] | None = None,
) -> GraphSummary | None:
    """The graph synthesis uses by default (modb.default_graph), built now when there is none, this
    role may build graphs and the scope is small enough; else None, having said why."""
    (may_build, standby) = conn.execute(
        "SELECT has_function_privilege('modb.build_transition_graph(text, text, text, float8)', "
        "'EXECUTE'), pg_is_in_recovery()"
    ).fetchone()
    (snippets,) = conn.execute(
        "SELECT count(*) FROM modb.snippets s WHERE %(c)s::text IS NULL "
        "OR s.collection_id = ANY (modb.collection_subtree(%(c)s))",
        {"c": collection},
    ).fetchone()
    command = "modb graph build NAME" + (f" --collection {collection}" if collection else "")
    if not may_build:
        say(f"this role cannot build graphs; a loader builds one with `{command}`")
        return None
    if standby:  # read-only: the primary builds it, and the standby replays it
        say(f"this is a hot standby, which cannot write: build one on the primary with `{command}`")
        return None
    if snippets > AUTO_BUILD_SNIPPETS:
        say(f"building one over {snippets:,} snippets takes minutes ({GROWTH}): `{command}`")
        return None
    name = auto_graph_name(profile, collection)
    say(
        f"building transition graph {name!r} over {snippets:,} snippets first (once, and again "
        f"after loads change its data; {GROWTH})"
    )
    started = time.perf_counter()
    try:
        graph = build_graph(conn, name, profile, collection, progress)
    except psycopg.Error as e:  # e.g. no part of the data keeps walking and turns both ways
        say(f"no graph: {e.diag.message_primary or e}")
        return None
    say(f"built in {time.perf_counter() - started:.0f} s: {describe(graph)}")
    return graph


def stale_graph_notes(conn: psycopg.Connection) -> list[str]:
    """After a load: the graphs it made stale, and when they are rebuilt (not now: a rebuild reads
    every snippet of its scope, minutes for tens of thousands, too much for a one-file load)."""
    (known,) = conn.execute(
        "SELECT to_regprocedure('modb.graph_is_current(bigint)') IS NOT NULL"
    ).fetchone()
    if not known:  # an extension before 0.12.0: `modb graph list` says which are stale
        return []
    notes = []
    for g in list_graphs(conn):
        if g.current:
            continue
        scope = f" --collection {g.collection}" if g.collection else ""
        when = (
            "the next `modb synth` over its data rebuilds it"
            if g.name == auto_graph_name(g.profile, g.collection)
            else f"`modb graph build {g.name}{scope}` rebuilds it"
        )
        notes.append(
            f"transition graph {g.name!r} no longer covers its data: synthesis falls back to "
            f"another graph or the plain rule until {when} ({GROWTH})"
        )
    return notes
