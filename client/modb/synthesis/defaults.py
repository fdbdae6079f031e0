"""What synthesis draws from and chooses among when its caller does not say, asked of the database
(modb.snippet_pools, modb.default_graph) so that modb.synthesize, `modb synth` and the Avatar agree:
without a collection or start, the skeleton-and-rate pool with the most snippets; without a graph,
the newest current transition graph over that data ("none" keeps the paper's plain rule)."""

from __future__ import annotations

from dataclasses import dataclass

import psycopg

NO_GRAPH = "none"  # Settings.graph / SET modb.graph: choose among every snippet


@dataclass(frozen=True)
class Pool:
    pose_key: str
    fps: float
    snippets: int
    collection: str | None  # the deepest collection holding all of it; None: only all together
    pools: int  # how many pools the database has


def largest_pool(conn: psycopg.Connection) -> Pool | None:
    row = conn.execute(
        "SELECT p.*, count(*) OVER () FROM modb.snippet_pools() p LIMIT 1"
    ).fetchone()
    return Pool(*row) if row else None


def describe_pool(pool: Pool) -> str:
    where = f"collection {pool.collection}" if pool.collection else "every collection"
    return (
        f"drawing from {where}: the largest of {pool.pools} skeleton-and-rate pools "
        f"({pool.snippets:,} snippets at {pool.fps:g} fps); --collection or --start chooses"
    )


def default_graph(conn: psycopg.Connection, profile: str, collection: str | None) -> str | None:
    """The newest current graph of the profile over the collection (or one containing it)."""
    return conn.execute("SELECT modb.default_graph(%s, %s)", [profile, collection]).fetchone()[0]


def profile_names_graph(conn: psycopg.Connection, profile: str) -> bool:
    """Whether the profile itself says which graph (or "none"): then the session leaves it so."""
    row = conn.execute(
        "SELECT settings ? 'graph' FROM modb.match_profiles WHERE name = %s", [profile]
    ).fetchone()
    return bool(row and row[0])


def session_graph(
    conn: psycopg.Connection, graph: str | None, profile: str, collection: str | None
) -> tuple[str, str | None]:
    """SET modb.graph for a chain with Settings.graph `graph`, and a note when it falls back."""
    if graph is not None or profile_names_graph(conn, profile):
        return graph or "", None
    chosen = default_graph(conn, profile, collection)
    return (chosen, None) if chosen else (NO_GRAPH, no_graph_note(profile, collection))


def no_graph_note(profile: str, collection: str | None) -> str:
    where = f"collection {collection}" if collection else "every collection"
    return (
        f"no current transition graph of profile {profile} over {where}: choosing among all its "
        "snippets (the paper's plain rule; goals are missed more and seams are rougher). "
        "`modb graph build NAME"
        + (f" --collection {collection}" if collection else "")
        + "` builds one"
    )
