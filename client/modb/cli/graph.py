"""`modb graph`: transition graphs, the snippets a chain can keep moving among."""

from __future__ import annotations

import argparse
import sys

import psycopg
from tqdm import tqdm

from modb.synthesis.graphs import build_graph, describe, list_graphs

from .common import Number, connect

MIN_TURN = Number(0.0, 180.0, unit="degrees")


def add_parser(sub: argparse._SubParsersAction) -> None:
    graph = sub.add_parser(
        "graph", help="transition graphs: the snippets a chain can keep moving among"
    )
    graph.add_argument("action", choices=["build", "list"])
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
    graph.add_argument(
        "--background",
        action="store_true",
        help="build: queue it as a job, print the job's id and return (`modb jobs show ID`)",
    )
    graph.add_argument("-q", "--quiet", action="store_true", help="no progress")
    graph.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        if args.action == "list":
            for g in list_graphs(conn):
                print(describe(g))
            return 0
        if not args.name:
            print(
                "modb graph build: name the graph (e.g. modb graph build locomotion --collection "
                "locomotion)",
                file=sys.stderr,
            )
            return 2
        from modb.jobs import schema
        from modb.jobs.graph_build import can_build_here

        if schema.installed(conn) and can_build_here(conn):
            return build_as_job(conn, args)
        if args.background:
            print(
                "modb graph build --background: "
                + (schema.NO_TABLES if not schema.installed(conn) else "the database's modb "
                   "extension is older than 0.19.0: ALTER EXTENSION modb UPDATE there"),
                file=sys.stderr,
            )  # fmt: skip
            return 2
        return build(conn, args.name, args.profile, args.collection, args.min_turn, args.quiet)


def build_as_job(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    """The build as a job: queued (--background: its id printed), else waited for with its progress,
    run by a worker when one is alive, else in this process."""
    from modb.database.dsn import resolve
    from modb.jobs.submit import (
        JobState,
        NotALoader,
        TooManyQueued,
        run_and_wait,
        submit,
        submitter,
        workers_alive,
    )

    conninfo = resolve(args.dsn)[0]
    try:
        who = submitter(conn)
    except NotALoader as e:
        print(f"modb graph build: {e}", file=sys.stderr)
        return 2
    arguments = {"name": args.name, "profile": args.profile, "collection": args.collection,
                 "min_turn_degrees": float(args.min_turn)}  # fmt: skip
    if args.background:
        try:
            print(submit(conn, "build_graph", who, **arguments))
        except TooManyQueued as e:
            print(f"modb graph build: {e}", file=sys.stderr)
            return 2
        if not workers_alive(conn):
            print(
                "modb graph build: no worker is running: the job waits for one (`modb worker`, "
                "or `modb db start --workers 1`)",
                file=sys.stderr,
            )
        return 0
    bar, lines_shown = None, 0

    def shown(state: JobState) -> None:
        nonlocal bar, lines_shown
        if args.quiet:
            return
        for line in state.log[lines_shown:]:
            (bar.write if bar else print)(f"job {state.id}: {line}", file=sys.stderr)
        lines_shown = len(state.log)
        if state.total and bar is None:
            bar = tqdm(total=state.total, unit=f" {state.unit}", file=sys.stderr, leave=False)
        if bar is not None:
            bar.update((state.done or 0) - bar.n)

    try:
        state = run_and_wait(conn, conninfo, "build_graph", who, shown, **arguments)
    except TooManyQueued as e:
        print(f"modb graph build: {e}", file=sys.stderr)
        return 2
    finally:
        if bar is not None:
            bar.close()
    if state.state != "done":
        print(
            f"modb graph build: job {state.id} {state.state}"
            + (f": {state.error}" if state.error else ""),
            file=sys.stderr,
        )
        return 1
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
