"""`modb`'s parser, put together from one module per command, and `main`, which runs a command and
turns the database errors every command can meet into a message and exit status 2."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

import psycopg

from modb.version import __version__

from . import (
    annotate,
    bench,
    catalog,
    db,
    demo,
    edit,
    export,
    graph,
    load,
    retarget,
    serve,
    split,
    synth,
    token,
)
from . import list as list_clips

# In `modb --help`'s order.
COMMANDS = (
    load,
    export,
    retarget,
    synth,
    list_clips,
    annotate,
    split,
    catalog,
    edit,
    demo,
    bench,
    graph,
    serve,
    token,
    db,
)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="modb", description="MoDB for PostgreSQL: motion capture in a database."
    )
    p.add_argument("--version", action="version", version=f"modb {__version__}")
    p.add_argument(
        "--dsn",
        help="libpq connection string (default: $MODB_DSN, then libpq's PG* environment, "
        "then the embedded cluster under $MODB_HOME)",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="say which database is used")
    sub = p.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except psycopg.OperationalError as e:
        print(
            f"modb: cannot connect to the database: {str(e).strip()}\n"
            f"  (check --dsn / MODB_DSN, or `modb db start` for the embedded one)",
            file=sys.stderr,
        )
        return 2
    except psycopg.Error as e:
        print(
            f"modb: database error: {e.diag.message_primary or e}"
            + (f"\n  hint: {e.diag.message_hint}" if e.diag.message_hint else ""),
            file=sys.stderr,
        )
        return 2
    except RuntimeError as e:  # NotInstalledError, ClusterError
        print(f"modb: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader of the output left early (`modb list | head`): not a failure, and no
        # traceback when Python flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
