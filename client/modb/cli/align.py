"""`modb align PRIMITIVE --collection C`: the primitive's examples (its annotation segments, e.g.
left_step from `modb annotate --steps`) aligned in time to a reference example, into
modb.processed_data (modb.align_primitive; a job where the database has job tables)."""

from __future__ import annotations

import argparse
import sys

from . import as_job
from .common import connect

SUMMARY = """
SELECT count(*), count(stale), max(n_frames) FILTER (WHERE reference),
       max(format('clip %%s frames %%s-%%s', clip_id, start_frame, end_frame))
           FILTER (WHERE reference)
  FROM modb.processed_data_status WHERE collection = %s AND primitive = %s
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    align = sub.add_parser(
        "align",
        help="align a motion primitive's examples in time (processed data for motion models)",
    )
    align.add_argument("primitive", metavar="PRIMITIVE", help="a segment name, e.g. left_step")
    align.add_argument(
        "--collection", required=True, help="the collection whose clips (and those below) hold them"
    )
    align.add_argument("-q", "--quiet", action="store_true", help="no progress")
    as_job.add_options(align, "align")
    align.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import psycopg

    with connect(args) as conn:
        as_a_job = as_job.usable(conn, args, "align", "0.21.0")
        if as_a_job is None:
            return 2
        if as_a_job:
            arguments = {"primitive": args.primitive, "collection": args.collection}
            done = as_job.run(conn, args, "align", "align", arguments)
            if done is None or isinstance(done, int):
                return done or 0
            r = done.result
            examples, aligned, deleted = r["examples"], r["aligned"], r["deleted"]
        else:
            try:
                with conn.transaction():
                    examples, aligned, deleted = conn.execute(
                        "SELECT * FROM modb.align_primitive(%s, %s)",
                        [args.primitive, args.collection],
                    ).fetchone()
            except psycopg.Error as e:
                hint = e.diag.message_hint
                print(f"modb align: {e.diag.message_primary}" + (f" ({hint})" if hint else ""),
                      file=sys.stderr)  # fmt: skip
                return 2
        rows, stale, frames, reference = conn.execute(
            SUMMARY, [args.collection, args.primitive]
        ).fetchone()
    print(
        f"{args.primitive} in {args.collection}: {examples} examples, {aligned} aligned now, "
        f"{deleted} stale rows deleted; reference {reference} ({frames} frames); "
        f"{rows} processed rows, {stale} stale"
    )
    return 0
