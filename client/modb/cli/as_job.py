"""The CLI's long commands as jobs: `--background` queues one and prints its id; without it the
command waits for it with a progress bar, run by a worker when one is alive, else in this process
(said once). Either way `modb jobs` lists it."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import psycopg
from tqdm import tqdm

from .common import Number

JOB_ID = Number(1, 2**63 - 1, whole=True)


def job_ids(text: str) -> list[int]:
    """--after 12,13: the jobs' ids (one value: it never swallows a command's operands)."""
    return [JOB_ID(part) for part in text.split(",")]


def add_options(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument(
        "--background",
        action="store_true",
        help=f"{what}: queue it as a job, print the job's id and return (`modb jobs show ID`)",
    )
    parser.add_argument(
        "--after",
        type=job_ids,
        metavar="JOB[,JOB...]",
        help="with --background: run once these jobs are done (cancelled if one fails)",
    )


def usable(
    conn: psycopg.Connection, args: argparse.Namespace, command: str, version: str
) -> bool | None:
    """True when the database runs jobs of this command (job tables, extension >= version); False
    when it does not and none was asked for; None (said) when --background or --after asked."""
    from modb.jobs import schema

    old = conn.execute(
        "SELECT string_to_array(extversion, '.')::int[] < string_to_array(%s, '.')::int[] "
        "FROM pg_extension WHERE extname = 'modb'",
        [version],
    ).fetchone()[0]
    if schema.installed(conn) and not old:
        if args.after and not args.background:
            print(f"modb {command}: --after goes with --background", file=sys.stderr)
            return None
        return True
    if args.background or args.after:
        why = schema.NO_TABLES
        if schema.installed(conn):
            why = f"the database's modb extension is older than {version}: ALTER EXTENSION modb "
            why += "UPDATE"
        print(f"modb {command} --background: {why}", file=sys.stderr)
        return None
    return False


def run(
    conn: psycopg.Connection,
    args: argparse.Namespace,
    command: str,
    kind: str,
    arguments: dict[str, Any],
):
    """The job queued (--background: None after printing its id) or run and waited for: its final
    JobState when done, else an exit status (said why)."""
    from modb.database.dsn import resolve
    from modb.jobs.submit import (
        CannotWait,
        JobState,
        NotALoader,
        NoWorker,
        TooManyQueued,
        run_and_wait,
        submit,
        submitter,
        workers_alive,
    )

    try:
        who = submitter(conn)
        if args.background:
            print(submit(conn, kind, who, after=args.after, **arguments))
            if not workers_alive(conn):
                print(
                    f"modb {command}: no worker is running: the job waits for one (`modb worker`, "
                    "or `modb db start --workers 1`)",
                    file=sys.stderr,
                )
            return None
    except (NotALoader, TooManyQueued, CannotWait) as e:
        print(f"modb {command}: {e}", file=sys.stderr)
        return 2
    bar, lines_shown = None, 0

    def shown(state: JobState) -> None:
        nonlocal bar, lines_shown
        if getattr(args, "quiet", False):
            return
        for line in state.log[lines_shown:]:
            (bar.write if bar else print)(f"job {state.id}: {line}", file=sys.stderr)
        lines_shown = len(state.log)
        if state.total and bar is None:
            bar = tqdm(total=state.total, unit=f" {state.unit}", file=sys.stderr, leave=False)
        if bar is not None:
            bar.update((state.done or 0) - bar.n)

    try:
        state = run_and_wait(conn, resolve(args.dsn)[0], kind, who, shown,
                             quiet=getattr(args, "quiet", False), **arguments)  # fmt: skip
    except (TooManyQueued, CannotWait, NotALoader) as e:
        print(f"modb {command}: {e}", file=sys.stderr)
        return 2
    except NoWorker as e:  # queued, as --background leaves it
        print(f"modb {command}: {e}", file=sys.stderr)
        return 0
    finally:
        if bar is not None:
            bar.close()
    if state.state != "done":
        print(
            f"modb {command}: job {state.id} {state.state}"
            + (f": {state.error}" if state.error else ""),
            file=sys.stderr,
        )
        return 1
    return state
