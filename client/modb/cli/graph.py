"""`modb graph`: transition graphs, the snippets a chain can keep moving among."""

from __future__ import annotations

import argparse
import sys

import psycopg
from modb.synthesis.graphs import build_graph, describe, list_graphs

from . import as_job
from .common import Number, connect

MIN_TURN = Number(0.0, 180.0, unit="degrees")


def add_parser(sub: argparse._SubParsersAction) -> None:
    graph = sub.add_parser(
        "graph", help="transition graphs: the snippets a chain can keep moving among"
    )
    graph.add_argument(
        "action", choices=["build", "list"], help="list: graphs of motion models too (their kind)"
    )
    graph.add_argument("name", nargs="?", help="build: the graph's name (rebuilt when it exists)")
    graph.add_argument(
        "--profile", default="default", help="build: the match profile whose level 0 is an edge"
    )
    graph.add_argument(
        "--collection", help="build: snippets of this collection (and those below it) only"
    )
    graph.add_argument(
        "--min-turn",
        type=MIN_TURN,
        default=45.0,
        metavar="DEGREES",
        help="build: keep the largest component whose snippets turn at least this much each way "
        f"({MIN_TURN.span}; default 45)",
    )
    as_job.add_options(graph, "build")
    graph.add_argument("-q", "--quiet", action="store_true", help="no progress")
    graph.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        if args.action == "list":
            for g in list_graphs(conn):
                print(describe(g))
            models_too = "SELECT to_regproc('modb.model_graph_problem') IS NOT NULL"
            if conn.execute(models_too).fetchone()[0]:
                from modb.models.graphs import listing

                for m in listing(conn):  # 0.23.0: graphs of motion models (modb model graph)
                    print(m.describe())
            return 0
        if not args.name:
            print(
                "modb graph build: name the graph (e.g. modb graph build locomotion --collection "
                "locomotion)",
                file=sys.stderr,
            )
            return 2
        as_a_job = as_job.usable(conn, args, "graph build", "0.19.0")
        if as_a_job is None:
            return 2
        if not as_a_job:
            return build(conn, args.name, args.profile, args.collection, args.min_turn, args.quiet)
        arguments = {"name": args.name, "profile": args.profile, "collection": args.collection,
                     "min_turn_degrees": float(args.min_turn)}  # fmt: skip
        done = as_job.run(conn, args, "graph build", "build_graph", arguments)
        if done is None or isinstance(done, int):
            return done or 0
        print(describe(next(g for g in list_graphs(conn) if g.name == args.name)))
        return 0


def build(
    conn: psycopg.Connection,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    min_turn: float = 45.0,
    quiet: bool = False,
) -> int:
    """`modb graph build NAME` (its options as arguments) on `conn`: its progress, the graph
    described, its exit status. `modb bench` builds its graphs through it."""
    try:
        g = build_graph(
            conn,
            name,
            profile,
            collection,
            progress=None if quiet else lambda text: print(text, file=sys.stderr),
            min_turn_degrees=min_turn,
        )
    except psycopg.Error as e:
        print(
            f"modb graph build: {e.diag.message_primary or e}"
            + (f" ({e.diag.message_hint})" if e.diag.message_hint else ""),
            file=sys.stderr,
        )
        return 1
    print(describe(g))
    return 0
