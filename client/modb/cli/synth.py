"""`modb synth`: a long strip synthesized toward goals, written as BVH, with its quality report."""

from __future__ import annotations

import argparse
import dataclasses
import sys

from modb.synthesis.chain import (
    MAX_ARRIVAL_RADIUS,
    MAX_BLEND_FRAMES,
    MAX_COORDINATE,
    MAX_EXCLUDE_SECONDS,
    MAX_ID,
    MAX_LEAD_TIME,
    MAX_SECONDS,
    Goal,
    NoContinuation,
    Settings,
    checked_goal,
)
from modb_kernel.model_synthesis import MAX_ARRIVAL_RADIUS_M

from modb.synthesis.defaults import NO_GRAPH, default_graph, largest_pool, profile_names_graph
from modb.synthesis.graphs import build_default_graph

from .common import (
    FPS,
    Number,
    connect,
    motion_format,
    positive,
    whole,
    writable,
    write_motion_file,
)

SECONDS = positive(MAX_SECONDS, "seconds")
ARRIVAL_RADIUS = positive(MAX_ARRIVAL_RADIUS, "metres")
EXCLUDE_SECONDS = Number(0.0, MAX_EXCLUDE_SECONDS, unit="seconds")
LEAD_TIME = Number(0.0, MAX_LEAD_TIME, unit="seconds")
BLEND = whole(0, MAX_BLEND_FRAMES, "frames")
SNIPPET = whole(1, MAX_ID)
MAX_MODEL_SECONDS = 600.0  # modb.synthesize_from_models's limit (the strip is one row)
SEED = whole(0, 2**31 - 1)
# options of snippet selection, which a walk on a graph of models has no use for
SELECTION_ONLY = ("collection", "start", "profile", "graph", "no_graph", "exclude_seconds",
                  "lead_time", "seam", "blend", "annotation")  # fmt: skip


def add_parser(sub: argparse._SubParsersAction) -> None:
    synth = sub.add_parser(
        "synth", help="synthesize a long strip toward goals and write it as BVH or glTF"
    )
    synth.add_argument(
        "--to",
        action=InOrder,
        default=[],
        metavar="X,Z",
        help="a goal in world metres (X, Z on the ground; the avatar starts at the origin facing "
        "+Z); "
        "repeat for waypoints, followed in order",
    )
    synth.add_argument(
        "--action",
        action=InOrder,
        default=[],
        metavar="NAME:X,Y,Z[:SECONDS]",
        help="with --models: walk to within reach of the point, come to rest, perform the graph's "
        "action NAME with its hand at the point (world metres, Y up) and stand; a repeated "
        "motion (a wave) faces the point where it stands, for SECONDS; repeatable, kept in "
        "order with the goals (e.g. --to 0,4 --action raise_right_hand:0.3,1.75,5)",
    )
    synth.add_argument(
        "--seconds", type=SECONDS, required=True, help=f"length of the strip ({SECONDS.span})"
    )
    synth.add_argument(
        "--out",
        required=True,
        help="the file to write: BVH, or glTF for a .glb or .gltf name (a skinned character with "
        "the animation); - for BVH on standard output; a device, FIFO or symlink's target is "
        "written into, a regular file replaced whole",
    )
    synth.add_argument("--fps", type=FPS, help=f"write at this frame rate ({FPS.span})")
    synth.add_argument(
        "--collection", help="draw snippets from this collection (and those below it)"
    )
    synth.add_argument(
        "--start",
        type=SNIPPET,
        help="the first snippet, a modb.snippets id (default: the best one for the first goal)",
    )
    synth.add_argument(
        "--models",
        metavar="GRAPH",
        help="walk a graph of motion models (modb model graph) instead of selecting snippets: "
        "the server's modb.synthesize_from_models, the same seed the same walk",
    )
    synth.add_argument(
        "--seed", type=SEED, help="with --models: the seed of the walk's choices (default 0)"
    )
    synth.add_argument("--profile", help="match profile (modb.match_profiles; default: default)")
    graph = synth.add_mutually_exclusive_group()
    graph.add_argument(
        "--graph",
        help="choose among this transition graph's snippets only (default: the newest current "
        "graph over the data, built first when there is none and this role can)",
    )
    graph.add_argument(
        "--no-graph",
        action="store_true",
        help="choose among every snippet (the paper's plain rule: goals missed more, rough seams)",
    )
    synth.add_argument(
        "--arrival-radius",
        type=ARRIVAL_RADIUS,
        default=0.5,
        help=f"a goal is reached this near ({ARRIVAL_RADIUS.span}, with --models at most "
        f"{MAX_ARRIVAL_RADIUS_M:g}; default 0.5)",
    )
    synth.add_argument(
        "--exclude-seconds",
        type=EXCLUDE_SECONDS,
        help=f"do not replay frames played this recently ({EXCLUDE_SECONDS.span}; default 2)",
    )
    synth.add_argument(
        "--lead-time",
        type=LEAD_TIME,
        help="issue each query this many seconds before the current snippet ends "
        f"({LEAD_TIME.span}; default 0)",
    )
    synth.add_argument(
        "--seam",
        choices=["inertialize", "blend", "none"],
        help="how a seam's jump is smoothed: inertialize (a decaying offset, the default), blend "
        "(spread over --blend frames), none (the snippets as captured)",
    )
    synth.add_argument(
        "--blend",
        type=BLEND,
        metavar="FRAMES",
        help=f"with --seam blend: over this many frames ({BLEND.span}; given alone, it means "
        "--seam blend)",
    )
    synth.add_argument(
        "--annotation",
        action="append",
        default=[],
        metavar="NAME",
        help="draw only snippets that lie wholly in segments named NAME (any of those given; "
        "!NAME: none of whose frames lie in one); repeatable",
    )
    synth.add_argument(
        "--foot-lock",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="hold each stance foot where it touched down, at the height its source holds it "
        "(the kernel's two-bone IK on the legs), in both families: the default; "
        "--no-foot-lock shows the seams' treatment alone, for comparison",
    )
    synth.add_argument(
        "--in-place",
        action="store_true",
        help="keep the skeleton's own top joint as placed (default: root motion, the travel on "
        "the top joint as engines take it; a top joint is added where the pelvis is the top)",
    )
    synth.add_argument(
        "--report", action="store_true", help="print the choices and the quality figures"
    )
    synth.add_argument(
        "--report-json",
        metavar="FILE",
        help="write the choices and figures as JSON (- for standard output)",
    )
    synth.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    synth.set_defaults(func=run)


class InOrder(argparse.Action):
    """--to and --action: each value in its own list and, with which option gave it, in
    `course`, so that goals and actions keep the order given."""

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        setattr(namespace, self.dest, [*getattr(namespace, self.dest, []), values])
        namespace.course = [*getattr(namespace, "course", []), (self.dest, values)]


def parse_goal(text: str) -> Goal:
    """'X,Z' (or 'X,Y,Z') world metres."""
    try:
        return checked_goal(text.split(","))
    except ValueError:
        raise ValueError(
            f"--to {text!r:.200}: expected X,Z in metres (each at most {MAX_COORDINATE:,.0f} "
            f"from the origin), e.g. --to 3,-4"
        ) from None


def prepare_default_graph(conn, settings, start: int | None, quiet: bool) -> None:
    """Builds the graph synthesis will use by default when there is none and this role can."""
    if profile_names_graph(conn, settings.profile):
        return
    collection = settings.collection
    if collection is None and start is None:
        pool = largest_pool(conn)
        collection = pool.collection if pool else None
    if default_graph(conn, settings.profile, collection) is None:

        def say(text: str) -> None:
            print(f"modb synth: {text}", file=sys.stderr)

        build_default_graph(
            conn,
            settings.profile,
            collection,
            say,
            None if quiet else lambda text: print(f"  {text}", file=sys.stderr),
        )


def run(args: argparse.Namespace) -> int:
    # numpy, scipy and synthesis on them (about 300 ms): not for `modb --help`
    from modb.provenance import as_meta, strip_sources
    from modb.resample import at_fps
    from modb.synthesis.root_motion import with_root_motion
    from modb.synthesis.source_frames import UnplaceableSkeleton
    from modb.synthesis.from_models import actions_in_course
    from modb.synthesis.synth import clip_names, report, synthesize

    from .synth_report import format_report, print_progress, write_report_json

    try:
        goals = [parse_goal(text) for text in args.to]
        course = getattr(args, "course", [])
        actions = actions_in_course(course)
    except ValueError as e:
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    if not goals and not actions:
        print("modb synth: give a goal (--to X,Z) or, with --models, an action (--action "
              "NAME:X,Y,Z)", file=sys.stderr)  # fmt: skip
        return 2
    if actions and args.models is None:
        print("modb synth: --action needs a graph of models (--models GRAPH): snippet selection "
              "has no actions", file=sys.stderr)  # fmt: skip
        return 2
    on_stdout = [
        name
        for name, used in (
            ("--out -", args.out == "-"),
            ("--report-json -", args.report_json == "-"),
            ("--report", args.report),
        )
        if used
    ]
    if len(on_stdout) > 1:
        print(
            f"modb synth: {' and '.join(on_stdout)} cannot share standard output: write all but "
            "one to a file",
            file=sys.stderr,
        )
        return 2
    if not (writable("synth", args.out) and writable("synth", args.report_json)):
        return 1
    if args.models is not None:
        return run_models(args, goals, actions)
    if args.seed is not None:
        print("modb synth: --seed goes with --models (snippet selection draws nothing at random)",
              file=sys.stderr)  # fmt: skip
        return 2
    try:
        settings = Settings(
            profile=args.profile or "default",
            collection=args.collection,
            graph=args.graph,
            arrival_radius=args.arrival_radius,
            exclude_seconds=2.0 if args.exclude_seconds is None else args.exclude_seconds,
            lead_time=args.lead_time or 0.0,
            blend_frames=args.blend or 0,
            seam=args.seam or ("blend" if args.blend else "inertialize"),
            foot_hold=args.foot_lock,
        )
    except ValueError as e:  # named by the setting: --lead-time is lead_time
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    if args.annotation:
        settings.knobs = {**settings.knobs, "annotations": ",".join(args.annotation)}
    if args.no_graph:
        settings.graph = NO_GRAPH
    with connect(args) as conn:
        if settings.graph is None:
            prepare_default_graph(conn, settings, args.start, args.quiet)
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
        for note in result.notes:
            print(f"modb synth: {note}", file=sys.stderr)
        strip = result.strip if args.in_place else with_root_motion(result.strip)
        if args.fps:
            strip = at_fps(strip, args.fps)
        sources = strip_sources(conn, [(c.clip_id, c.version) for c in result.chain])
        strip = dataclasses.replace(strip, meta={**strip.meta, "sources": as_meta(sources)})
        if not write_motion_file("synth", strip, args.out, motion_format(args.out)):
            return 1
        print(
            f"wrote {'the strip to standard output' if args.out == '-' else args.out}: "
            f"{strip.n_frames} frames at {strip.fps:g} fps "
            f"({(strip.n_frames - 1) / strip.fps:.1f} s), {len(result.chain)} "
            f"snippets",
            file=sys.stderr,
        )
        if result.stopped:
            print(f"modb synth: the strip ended early: {result.stopped}", file=sys.stderr)
        if args.report or args.report_json:
            try:
                rep = report(conn, result)
                if args.report:
                    print(format_report(result, rep, clip_names(conn, result.chain), sources))
                if args.report_json:
                    write_report_json(args.report_json, result, rep, sources, allow_stdout=True)
            except ValueError as e:
                print(f"modb synth: no quality report: {e}", file=sys.stderr)
                return 1
            except BrokenPipeError:
                raise  # the reader left early: main() exits 0
            except OSError as e:
                print(
                    f"modb synth: cannot write {args.report_json}: {e.strerror or e}",
                    file=sys.stderr,
                )
                return 1
    return 1 if result.stopped else 0


def run_models(args: argparse.Namespace, goals: list[Goal], actions: list[dict]) -> int:
    """`modb synth --models GRAPH`: the walk modb.synthesize_from_models makes, written out."""
    import psycopg

    from modb.resample import at_fps
    from modb.synthesis.from_models import Source, measure, synthesize
    from modb.synthesis.root_motion import with_root_motion

    from .synth_report import format_model_report, write_model_report_json

    used = [o for o in SELECTION_ONLY if getattr(args, o) not in (None, [], False)]
    given = [f"--{o.replace('_', '-')}" for o in used]
    if given:
        print(f"modb synth: {', '.join(given)} select{'s' if len(given) == 1 else ''} snippets: "
              "a walk on a graph of models (--models) has no use for "
              f"{'it' if len(given) == 1 else 'them'}", file=sys.stderr)  # fmt: skip
        return 2
    if args.arrival_radius > MAX_ARRIVAL_RADIUS_M:
        print(f"modb synth: --arrival-radius {args.arrival_radius:g}: a walk on a graph of models "
              f"takes at most {MAX_ARRIVAL_RADIUS_M:g} m", file=sys.stderr)  # fmt: skip
        return 2
    seed = args.seed or 0
    if args.seconds > MAX_MODEL_SECONDS:
        print(f"modb synth: --seconds {args.seconds:g}: a walk on a graph of models lasts at most "
              f"{MAX_MODEL_SECONDS:g} s", file=sys.stderr)  # fmt: skip
        return 2
    with connect(args) as conn:
        if not args.foot_lock:
            conn.execute("SELECT set_config('modb.foot_hold', 'off', false)")
        try:
            strip = synthesize(conn, args.models, [(g[0], g[-1]) for g in goals], args.seconds,
                               seed, args.arrival_radius, actions)  # fmt: skip
        except psycopg.Error as e:
            hint = e.diag.message_hint
            print(f"modb synth: {e.diag.message_primary}" + (f" ({hint})" if hint else ""),
                  file=sys.stderr)  # fmt: skip
            return 1
        for note in strip.report["notes"]:
            print(f"modb synth: {note}", file=sys.stderr)
        motion = strip.motion
        out = motion if args.in_place else with_root_motion(motion)
        if args.fps:
            out = at_fps(out, args.fps)
        if not write_motion_file("synth", out, args.out, motion_format(args.out)):
            return 1
        print(f"wrote {'the strip to standard output' if args.out == '-' else args.out}: "
              f"{out.n_frames} frames at {out.fps:g} fps ({(out.n_frames - 1) / out.fps:.1f} s), "
              f"{len(strip.report['steps'])} steps of graph {args.models} (seed {seed})",
              file=sys.stderr)  # fmt: skip
        if args.report or args.report_json:
            try:
                figures = measure(strip, Source.of(conn, args.models))
            except ValueError as e:
                print(f"modb synth: no quality report: {e}", file=sys.stderr)
                return 1
            if args.report:
                print(format_model_report(figures, strip.report))
            if args.report_json:
                write_model_report_json(args.report_json, figures, strip.report)
    return 0
