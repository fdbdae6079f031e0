"""`modb worker`: run queued jobs (graph builds, ...) in this machine's processes, for the database
--dsn names (this machine's embedded one, or another's)."""

from __future__ import annotations

import argparse
import sys

from .common import Number, connect

CONCURRENCY = Number(1, 64, whole=True, unit="processes")
STALLED = Number(1, 86400, unit="seconds")
KEEP = Number(0, 3650, above=True, unit="days")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "worker",
        help="run queued jobs here (graph builds, ...): any machine that reaches the database",
    )
    p.add_argument(
        "--concurrency",
        type=CONCURRENCY,
        default=1,
        metavar="N",
        help=f"processes, one job each at a time ({CONCURRENCY.span}; default 1)",
    )
    p.add_argument(
        "--queues",
        nargs="+",
        metavar="QUEUE",
        help="only these queues (default: all; graphs, clips, primitives)",
    )
    p.add_argument(
        "--stalled-after",
        type=STALLED,
        default=30.0,
        metavar="SECONDS",
        help="a worker silent this long is gone: its running jobs are queued again (default 30)",
    )
    p.add_argument(
        "--keep-days",
        type=KEEP,
        default=30.0,
        metavar="DAYS",
        help="finished jobs (their progress and log too) are deleted after this long (default 30)",
    )
    p.add_argument(
        "--init",
        action="store_true",
        help="make the job tables in the database (as a superuser, once) and exit",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.database.dsn import resolve
    from modb.jobs import schema, worker

    from modb.jobs.tasks import QUEUES

    unknown = sorted(set(args.queues or ()) - set(QUEUES.values()))
    if unknown:
        print(
            f"modb worker: no queue {unknown[0]!r}: the queues are "
            f"{', '.join(sorted(set(QUEUES.values())))}",
            file=sys.stderr,
        )
        return 2
    conninfo = resolve(args.dsn)[0]  # with its password, which conn.info.dsn leaves out
    with connect(args) as conn:
        if args.init:
            made = schema.install(conn)
            print("modb worker: job tables " + ("made" if made else "already there"))
            return 0
        if not schema.installed(conn) or not schema.current(conn):
            why = schema.NO_TABLES if not schema.installed(conn) else schema.OLD_TABLES
            print(f"modb worker: {why}", file=sys.stderr)
            return 2
    print(
        f"modb worker: {args.concurrency} process(es) taking jobs from "
        f"{', '.join(args.queues) if args.queues else 'every queue'}; Ctrl-C stops",
        file=sys.stderr,
    )
    return worker.run(
        conninfo,
        int(args.concurrency),
        args.queues,
        float(args.stalled_after),
        float(args.keep_days),
    )
