"""`modb jobs`: list, show, cancel and retry the database's jobs (modb.jobs)."""

from __future__ import annotations

import argparse
import json
import sys

from .common import Number, connect

JOB_ID = Number(1, 2**63 - 1, whole=True)
LIMIT = Number(1, 10000, whole=True, unit="jobs")

LIST = """
SELECT id, kind, state, submitter, done, total, unit, started_at, finished_at, arguments
  FROM modb.jobs ORDER BY id DESC LIMIT %s
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("jobs", help="queued, running and finished jobs: list, show, cancel, retry")
    p.add_argument("action", choices=["list", "show", "cancel", "retry"])
    p.add_argument("job", nargs="?", type=JOB_ID, help="show, cancel, retry: the job's id")
    p.add_argument(
        "--limit",
        type=LIMIT,
        default=20,
        help=f"list: the newest this many ({LIMIT.span}; default 20)",
    )
    p.set_defaults(func=run)


def progress_text(done, total, unit) -> str:
    if total is None:
        return ""
    return f"{done:,}/{total:,} {unit or ''}".rstrip()


def run(args: argparse.Namespace) -> int:
    from modb.jobs import schema
    from modb.jobs.submit import job_document

    with connect(args) as conn:
        if not schema.installed(conn):
            print(f"modb jobs: {schema.NO_TABLES}", file=sys.stderr)
            return 2
        if args.action == "list":
            rows = conn.execute(LIST, [args.limit]).fetchall()
            print("id\tkind\tstate\tsubmitter\tprogress\tstarted\tfinished\targuments")
            for id_, kind, state, who, done, total, unit, started, finished, arguments in rows:
                times = [t.isoformat(timespec="seconds") if t else "-" for t in (started, finished)]
                print(
                    f"{id_}\t{kind}\t{state}\t{who}\t{progress_text(done, total, unit) or '-'}\t"
                    f"{times[0]}\t{times[1]}\t{json.dumps(arguments)}"
                )
            return 0
        if args.job is None:
            print(f"modb jobs {args.action}: name the job (modb jobs list)", file=sys.stderr)
            return 2
        job = job_document(conn, args.job)
        if job is None:
            print(f"modb jobs: no job {args.job}", file=sys.stderr)
            return 2
        if args.action == "show":
            print(json.dumps(job, indent=2))
            return 0
        return change(args, job)


def change(args: argparse.Namespace, job: dict) -> int:
    from modb.jobs.submit import NotALoader, TooManyQueued, cancel, retry, submitter

    with connect(args) as conn:
        try:
            who = submitter(conn)
        except NotALoader as e:
            print(f"modb jobs {args.action}: {e}", file=sys.stderr)
            return 2
        if args.action == "cancel":
            if not cancel(conn, job["id"]):
                print(f"modb jobs cancel: job {job['id']} is {job['state']}", file=sys.stderr)
                return 2
            print(
                f"job {job['id']}: "
                + ("cancelled" if job["state"] == "queued" else "stops at its next step")
            )
            return 0
        if job["state"] not in ("failed", "cancelled"):
            print(
                f"modb jobs retry: job {job['id']} is {job['state']} (a failed or cancelled job is "
                "retried)",
                file=sys.stderr,
            )
            return 2
        try:
            again = retry(conn, job, who)
        except TooManyQueued as e:
            print(f"modb jobs retry: {e}", file=sys.stderr)
            return 2
        print(f"job {job['id']}: queued again" + (f" as job {again}" if again != job["id"] else ""))
        return 0
