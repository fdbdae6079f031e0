"""`modb`'s parser, put together from one module per command, and `main`, which runs a command and
turns the database errors every command can meet into a message and exit status 2 (cli.errors)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from modb.version import __version__

from . import (
    align,
    annotate,
    bench,
    catalog,
    db,
    demo,
    edit,
    export,
    graph,
    jobs,
    load,
    model,
    retarget,
    serve,
    split,
    synth,
    token,
    worker,
)
from . import list as list_clips
from .errors import reporting_errors

# In `modb --help`'s order.
COMMANDS = (
    load,
    export,
    retarget,
    synth,
    list_clips,
    annotate,
    align,
    model,
    split,
    catalog,
    edit,
    demo,
    bench,
    graph,
    worker,
    jobs,
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
    return reporting_errors(lambda: args.func(args))


if __name__ == "__main__":
    sys.exit(main())
