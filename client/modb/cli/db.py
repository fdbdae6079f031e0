"""`modb db`: the embedded database cluster (start, stop, status, url)."""

from __future__ import annotations

import argparse
import sys


def add_parser(sub: argparse._SubParsersAction) -> None:
    db = sub.add_parser("db", help="the embedded database cluster")
    db.add_argument("action", choices=["start", "stop", "status", "url"])
    db.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.database.cluster import Cluster, ClusterError

    cluster = Cluster.default()
    try:
        if args.action == "start":
            cluster.start()
            print(f"running: {cluster.dsn()}")
        elif args.action == "stop":
            cluster.stop()
            print(cluster.status())
        elif args.action == "status":
            print(cluster.status())
            return 0 if cluster.is_running() else 3
        elif args.action == "url":
            print(cluster.dsn())
    except ClusterError as e:
        print(f"modb db {args.action}: {e}", file=sys.stderr)
        return 1
    return 0
