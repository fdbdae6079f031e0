"""`modb db`: the embedded database cluster (start, stop, status, url) and its hot standbys
(`modb db replica add|list|url|remove|promote`)."""

from __future__ import annotations

import argparse
import json
import sys

import psycopg

from modb.database import workers
from modb.database.cluster import Cluster, ClusterError
from modb.database.replicas import Replicas

from .common import Number

WORKERS = Number(1, 64, whole=True, unit="processes")


def add_parser(sub: argparse._SubParsersAction) -> None:
    db = sub.add_parser("db", help="the embedded database cluster")
    actions = db.add_subparsers(dest="action", required=True, metavar="ACTION")
    for action, text in (
        ("start", "create the cluster if needed, start it and its standbys, update the extension"),
        ("stop", "stop the primary (and the job workers it started)"),
        ("status", "whether the primary runs (exit 3 when not)"),
        ("url", "the primary's conninfo"),
    ):
        parser = actions.add_parser(action, help=text)
        parser.set_defaults(func=run)
        if action == "start":
            parser.add_argument(
                "--workers",
                type=WORKERS,
                default=0,
                metavar="N",
                help="also start N job worker processes (`modb worker`; default none: jobs then "
                "run in the command that waits for them)",
            )
    replica = actions.add_parser(
        "replica", help="hot standbys of the embedded database (streaming replication)"
    )
    steps = replica.add_subparsers(dest="step", required=True, metavar="STEP")
    add = steps.add_parser("add", help="make a standby streaming from the primary, and start it")
    add.add_argument("name", metavar="NAME", help="lower-case letters, digits and _")
    listing = steps.add_parser("list", help="each standby's conninfo, state and replay lag")
    listing.add_argument("--json", action="store_true", help="as JSON")
    url = steps.add_parser("url", help="a standby's conninfo, for --dsn, psql and other readers")
    url.add_argument("name", metavar="NAME")
    remove = steps.add_parser("remove", help="stop a standby, drop its slot, delete its data")
    remove.add_argument("name", metavar="NAME")
    promote = steps.add_parser(
        "promote", help="make a standby the primary (the old one stopped); the others follow it"
    )
    promote.add_argument("name", metavar="NAME")
    replica.set_defaults(func=run_replica)


def run(args: argparse.Namespace) -> int:
    cluster = Cluster.default()
    try:
        if args.action == "start":
            cluster.start()
            print(f"running: {cluster.dsn()}")
            for r in Replicas(cluster).all():
                r.node.run_server()
                print(f"standby {r.name} running: {r.node.dsn()}")
            if args.workers:
                pid = workers.start(cluster, int(args.workers))
                print(f"job workers running (process {pid}, log {cluster.home / 'workers.log'})")
        elif args.action == "stop":
            if workers.stop(cluster):
                print("job workers stopped")
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


def run_replica(args: argparse.Namespace) -> int:
    replicas = Replicas(Cluster.default())
    try:
        if args.step == "add":
            r = replicas.add(args.name)
            print(f"standby {r.name} streaming: {r.node.dsn()}")
        elif args.step == "url":
            print(replicas.get(args.name).node.dsn())
        elif args.step == "remove":
            replicas.remove(args.name)
            print(f"standby {args.name} removed (its slot dropped)")
        elif args.step == "promote":
            old_data = replicas.cluster.datadir
            r = replicas.promote(args.name)
            print(f"{r.name} is the primary now: {Cluster.default().dsn()}")
            if old_data != Cluster.default().datadir:
                print(
                    f"the old primary's data ({old_data}) is no longer used; delete it when you "
                    "no longer need it"
                )
        else:
            rows = replicas.status()
            if args.json:
                print(json.dumps(rows, indent=1))
            elif not rows:
                print("no standbys (`modb db replica add NAME` makes one)")
            for row in [] if args.json else rows:
                state = "running" if row["running"] else "stopped"
                if row["streaming"]:
                    state += f", {row['replay_lag_bytes']} bytes behind"
                    state += f" ({row['replay_lag']})" if row["replay_lag"] else ""
                elif row["running"]:
                    state += ", not streaming"
                if row["slot"] == "lost":
                    state += ", its slot LOST (remove and add it again)"
                print(f"{row['name']:12s} {state:40s} {row['dsn']}")
    except (ClusterError, psycopg.Error) as e:
        print(f"modb db replica {args.step}: {str(e).strip()}", file=sys.stderr)
        return 1
    return 0
