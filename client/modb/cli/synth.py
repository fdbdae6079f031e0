"""`modb synth`: a long strip synthesized toward goals, written as BVH, with its quality report."""

from __future__ import annotations

import argparse
import sys

from .common import connect, write_bvh_file


def add_parser(sub: argparse._SubParsersAction) -> None:
    synth = sub.add_parser("synth", help="synthesize a long strip toward goals and write it as BVH")
    synth.add_argument(
        "--to",
        action="append",
        required=True,
        metavar="X,Z",
        help="a goal in world metres (X, Z on the ground; the avatar starts at the origin facing "
        "+Z); "
        "repeat for waypoints, followed in order",
    )
    synth.add_argument("--seconds", type=float, required=True, help="length of the strip")
    synth.add_argument("--out", required=True, help="the BVH file to write")
    synth.add_argument(
        "--collection", help="draw snippets from this collection (and those below it)"
    )
    synth.add_argument(
        "--start", type=int, help="the first snippet (default: the best one for the first goal)"
    )
    synth.add_argument("--profile", default="default", help="match profile (modb.match_profiles)")
    synth.add_argument(
        "--graph", help="choose among this transition graph's snippets only (`modb graph build`)"
    )
    synth.add_argument("--arrival-radius", type=float, default=0.5, help="metres (default 0.5)")
    synth.add_argument(
        "--exclude-seconds",
        type=float,
        default=2.0,
        help="do not replay frames played this recently (default 2)",
    )
    synth.add_argument(
        "--lead-time",
        type=float,
        default=0.0,
        help="issue each query this many seconds before the current snippet ends (default 0)",
    )
    synth.add_argument(
        "--blend",
        type=int,
        default=0,
        metavar="FRAMES",
        help="blend each seam over this many frames (default 0: snippets as captured)",
    )
    synth.add_argument(
        "--report", action="store_true", help="print the choices and the quality figures"
    )
    synth.add_argument(
        "--report-json", metavar="FILE", help="write the choices and figures as JSON"
    )
    synth.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    synth.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.synthesis.avatar import NoContinuation, Settings
    from modb.synthesis.source_frames import UnplaceableSkeleton
    from modb.synthesis.synth import (
        clip_names,
        format_report,
        parse_goal,
        print_progress,
        report,
        synthesize,
        write_report_json,
    )

    try:
        goals = [parse_goal(text) for text in args.to]
    except ValueError as e:
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    if not args.seconds > 0:
        print("modb synth: --seconds must be positive", file=sys.stderr)
        return 2
    try:
        settings = Settings(
            profile=args.profile,
            collection=args.collection,
            graph=args.graph,
            arrival_radius=args.arrival_radius,
            exclude_seconds=args.exclude_seconds,
            lead_time=args.lead_time,
            blend_frames=args.blend,
        )
    except ValueError as e:  # named by the setting: --lead-time is lead_time
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    with connect(args) as conn:
        try:
            result = synthesize(
                conn,
                goals,
                args.seconds,
                settings,
                args.start,
                progress=None if args.quiet else print_progress(args.seconds),
            )
        except (NoContinuation, UnplaceableSkeleton, ValueError) as e:
            print(f"modb synth: {e}", file=sys.stderr)
            return 1
        if not write_bvh_file("synth", result.strip, args.out):
            return 1
        print(
            f"wrote {args.out}: {result.strip.n_frames} frames at {result.strip.fps:g} fps "
            f"({(result.strip.n_frames - 1) / result.strip.fps:.1f} s), {len(result.chain)} "
            f"snippets",
            file=sys.stderr,
        )
        if result.stopped:
            print(f"modb synth: the strip ended early: {result.stopped}", file=sys.stderr)
        if args.report or args.report_json:
            try:
                rep = report(conn, result, args.collection)
                if args.report:
                    print(format_report(result, rep, clip_names(conn, result.chain)))
                if args.report_json:
                    write_report_json(args.report_json, result, rep)
            except ValueError as e:
                print(f"modb synth: no quality report: {e}", file=sys.stderr)
                return 1
            except OSError as e:
                print(
                    f"modb synth: cannot write {args.report_json}: {e.strerror or e}",
                    file=sys.stderr,
                )
                return 1
    return 1 if result.stopped else 0
