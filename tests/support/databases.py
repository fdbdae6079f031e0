"""Test databases: a scratch database for a module, what a query's plan ran, what a database
holds."""

from __future__ import annotations

import contextlib

import psycopg

from .shared import create_database, drop_database

# conftest's `locomotion` fixture (the demo's database): the transition graph the demo builds, and
# the collection of Bandai dataset 2's locomotion clips it covers
GRAPH = "demo"
COLLECTION = "demo/bandai-2/locomotion"


@contextlib.contextmanager
def scratch_database(cluster, name: str):
    """A database with the extension for a whole test module (dropped at the end)."""
    dsn = create_database(cluster, name)
    try:
        yield dsn
    finally:
        drop_database(cluster, name)


def plan_nodes(conn: psycopg.Connection, sql: str, params=()) -> list[dict]:
    """Every node of the plan EXPLAIN (ANALYZE, FORMAT JSON) shows for a query, depth first."""
    explained = conn.execute("EXPLAIN (ANALYZE, FORMAT JSON) " + sql, params).fetchone()[0]
    nodes, todo = [], [explained[0]["Plan"]]
    while todo:
        node = todo.pop()
        nodes.append(node)
        todo.extend(reversed(node.get("Plans", [])))
    return nodes


def counts(db) -> tuple[int, ...]:
    """How many collections, skeletons, clips and clip versions the database holds."""
    return tuple(
        db.execute(f"SELECT count(*) FROM modb.{t}").fetchone()[0]
        for t in ("collections", "skeletons", "clips", "clip_versions")
    )
