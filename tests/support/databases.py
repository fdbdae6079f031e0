"""Test databases: a scratch database for a module, what a query's plan ran, what a database
holds."""

from __future__ import annotations

import contextlib

import psycopg

GRAPH = "locomotion"  # the transition graph of conftest's `locomotion` fixture


@contextlib.contextmanager
def scratch_database(cluster, name: str):
    """A database with the extension for a whole test module (dropped at the end)."""
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}"')
        admin.execute(f'CREATE DATABASE "{name}"')
    with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb CASCADE")
    try:
        yield cluster.dsn(name)
    finally:
        with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
            admin.execute(f'DROP DATABASE "{name}" WITH (FORCE)')


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
