"""What several commands share: the connection the global options name, and writing a BVH file."""

from __future__ import annotations

import argparse
import sys

import psycopg


def connect(args: argparse.Namespace) -> psycopg.Connection:
    """The database `--dsn` names (or $MODB_DSN, libpq's environment, the embedded cluster)."""
    from modb.database.connection import connect
    from modb.database.dsn import resolve

    conninfo, origin = resolve(args.dsn)
    if args.verbose:
        print(f"database: {origin}", file=sys.stderr)
    return connect(conninfo)


def write_bvh_file(command: str, motion, path: str) -> bool:
    """Writes `motion` to `path`; if it cannot, False, with the reason on stderr."""
    from modb.bvh_export import write_bvh_file

    try:
        write_bvh_file(motion, path)
    except OSError as e:
        print(f"modb {command}: cannot write {path}: {e.strerror or e}", file=sys.stderr)
        return False
    return True
