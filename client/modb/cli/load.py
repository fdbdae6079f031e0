"""`modb load`: BVH and ASF/AMC files and directories into the database."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

import psycopg
from tqdm import tqdm

from modb.loader.errors import MotionFileError
from modb.loader.sources import find_sources
from modb.synthesis.graphs import stale_graph_notes

from .common import FPS, connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    load = sub.add_parser("load", help="load BVH and ASF/AMC files and directories (recursively)")
    load.add_argument("paths", nargs="+", metavar="PATH")
    load.add_argument(
        "--collection", help="collection path a/b (default: named after the directory)"
    )
    load.add_argument(
        "--units",
        default="auto",
        help="auto | m | cm | mm | in | metres per unit (default auto: judged from the figure's "
        "size)",
    )
    fps = FPS
    load.add_argument(
        "--fps", type=fps, help=f"AMC frame rate, {fps.span} (AMC files carry none; default 120)"
    )
    load.add_argument(
        "--allow-truncated",
        action="store_true",
        help="drop an AMC file's incomplete last frame with a warning instead of refusing the file",
    )
    load.add_argument(
        "--asf", help="the ASF skeleton for every AMC file (default: paired by folder and name)"
    )
    load.add_argument(
        "--no-snippets",
        action="store_true",
        help="store the clips only (modb.build_snippets() cuts them later)",
    )
    load.add_argument(
        "--mirror",
        action="store_true",
        help="also add each clip's mirror image as snippets (through the skeleton's left/right "
        "pairs)",
    )
    load.add_argument(
        "--keep-going", action="store_true", help="load the good files, list the bad, exit non-zero"
    )
    load.add_argument(
        "--licence",
        metavar="TEXT",
        help="the terms of use of every file loaded (default: the first line of the nearest "
        "LICENSE file in its folder or up to three folders above; exports of what is made from "
        "the clips name it)",
    )
    load.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    load.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    return load_paths(
        lambda: connect(args),
        args.paths,
        args.collection,
        units=args.units,
        fps=args.fps,
        allow_truncated=args.allow_truncated,
        asf=args.asf,
        snippets=not args.no_snippets,
        mirrored=args.mirror,
        licence=args.licence,
        keep_going=args.keep_going,
        quiet=args.quiet,
    )


def load_paths(
    connect: Callable[[], psycopg.Connection],
    paths: Sequence[str],
    collection: str | None = None,
    *,
    units: str = "auto",
    fps: float | None = None,
    allow_truncated: bool = False,
    asf: str | None = None,
    snippets: bool = True,
    mirrored: bool = False,
    keep_going: bool = False,
    quiet: bool = False,
    licence: str | None = None,
) -> int:
    """`modb load PATHS` (its options as arguments) on the database `connect()` opens: the loader's
    load_files with the command's progress bar, messages and exit status. `modb demo` and `modb
    bench` load through it too."""
    # numpy (60 ms), which the loader's readers use: not for `modb --help`
    from modb.loader.ingest import load_files
    from modb.loader.reading import ReadOptions
    from modb.loader.units import UnitsError, parse_units

    try:
        parsed_units = parse_units(units)
        sources = find_sources(paths, collection, asf)
    except (UnitsError, MotionFileError) as e:
        print(f"modb load: {e}", file=sys.stderr)
        return 2
    if not sources:
        print(
            "modb load: no motion files (.bvh, .amc) found in " + " ".join(paths),
            file=sys.stderr,
        )
        return 2
    with (
        connect() as conn,
        tqdm(
            total=len(sources), unit="file", disable=quiet or len(sources) < 2, file=sys.stderr
        ) as bar,
    ):

        def progress(result) -> None:
            bar.update(1)
            if result.status == "failed":
                bar.write(f"error: {result.message}", file=sys.stderr)
            elif result.message:
                bar.write(f"note: {result.path}: {result.message}", file=sys.stderr)
            if result.joint_map_note:
                bar.write(f"note: {result.joint_map_note}", file=sys.stderr)

        options = ReadOptions(
            units=parsed_units,
            units_text=units,
            fps=fps,
            allow_truncated=allow_truncated,
            warn=lambda message: bar.write(f"warning: {message}", file=sys.stderr),
            licence=licence,
        )
        summary = load_files(
            conn,
            sources,
            options,
            keep_going,
            progress,
            snippets=snippets,
            mirrored=mirrored,
        )
    if not quiet:
        rules = list(dict.fromkeys(r.units_rule for r in summary.results if r.units_rule))
        for rule in rules[:3]:
            print(rule, file=sys.stderr)
        if len(rules) > 3:
            print(f"... and {len(rules) - 3} more files with their own figures", file=sys.stderr)
        print(summary.describe())
        if summary.count("loaded"):
            with connect() as conn:
                for note in stale_graph_notes(conn):
                    print(note, file=sys.stderr)
    if summary.failed:
        if keep_going:
            print(f"{len(summary.failed)} file(s) not loaded:", file=sys.stderr)
            for r in summary.failed:
                print(f"  {r.message}", file=sys.stderr)
        elif len(summary.results) < len(sources):
            print(
                f"stopped at the first bad file; {len(sources) - len(summary.results)} not tried "
                f"(--keep-going loads the good ones)",
                file=sys.stderr,
            )
        return 1
    return 0
