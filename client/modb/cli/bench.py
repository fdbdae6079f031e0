"""`modb bench`: one subcommand per benchmark, each with its own options (results go in
BENCHMARKS.md). The benchmarks themselves are modules of modb.bench."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Sequence
from pathlib import Path

import psycopg

from modb.database.cluster import Cluster
from modb.database.dsn import resolve
from modb.synthesis.chain import MAX_SECONDS, Settings

from . import graph as graph_command
from .common import SEED, connect, connect_to, positive, whole
from .errors import reporting_errors
from .load import load_paths

ROUNDS = whole(1, 1000)
QUERIES = whole(1, 100_000)
BASELINE_QUERIES = whole(0, 100_000)
TAIL_QUERIES = whole(10, 1_000_000)
TAIL_EXACT = whole(0, 100_000)
PGBENCH_SECONDS = whole(1, 3600, "seconds")
COURSE_SECONDS = positive(MAX_SECONDS, "seconds")
AVATARS = whole(1, 500)
STANDBYS = whole(0, 8)
CROWD_SECONDS = whole(10, 3600, "seconds")
MIXED_SECONDS = whole(1, 3600, "seconds")
WRITERS = whole(0, 64)
READERS = whole(0, 64)
MIXED_AVATARS = whole(0, 8)  # modb serve's default limit on one node
MIXED_CLIPS = whole(3, 100)
MAX_SIZE = 10_000_000  # snippets in a scaled copy of the database


def sizes(text: str) -> list[int | None]:
    """--sizes: snippet counts from 1 to MAX_SIZE, or 'all' (None), separated by commas."""
    counts = whole(1, MAX_SIZE)
    try:
        return [None if v == "all" else counts(v) for v in text.split(",")]
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be snippet counts from 1 to {MAX_SIZE} or 'all', separated by commas, got "
            f"{text!r:.100}"
        ) from None


def names(text: str) -> list[str]:
    """--actions: node names separated by commas."""
    out = [v.strip() for v in text.split(",") if v.strip()]
    if not out:
        raise argparse.ArgumentTypeError("name at least one action, e.g. raise_right_hand")
    return out


TARGET_GROUPS = ("inside", "10", "20", "30", "out")


def target_groups(text: str) -> list[str]:
    """--groups: some of TARGET_GROUPS separated by commas."""
    out = [v.strip() for v in text.split(",")]
    if not out or any(v not in TARGET_GROUPS for v in out):
        raise argparse.ArgumentTypeError(
            f"must be some of {', '.join(TARGET_GROUPS)} separated by commas, got {text!r:.100}"
        )
    return out


def add_parser(sub: argparse._SubParsersAction) -> None:
    bench = sub.add_parser("bench", help="benchmarks (results go in BENCHMARKS.md)")
    benchmarks = bench.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")

    load = benchmarks.add_parser(
        "load", help="parse and load speed on real BVH files, beside bvhio"
    )
    load.add_argument("--data", help="folder of .bvh files (default ../shared/mocap/bandai-1)")
    load.add_argument("--rounds", type=ROUNDS, default=3, help=f"rounds ({ROUNDS.span}; default 3)")
    load.set_defaults(func=run_load)

    select = benchmarks.add_parser(
        "select",
        help="selection latency on the database beside a sequential scan of the same query",
    )
    select.add_argument(
        "--queries",
        type=QUERIES,
        default=200,
        help=f"number of seeded queries ({QUERIES.span}; default 200)",
    )
    select.add_argument(
        "--seed", type=SEED, default=1, help=f"random seed ({SEED.span}; default 1)"
    )
    select.add_argument("--profile", default="default", help="match profile (default: default)")
    select.add_argument(
        "--graph",
        help="time level 0 from this transition graph's stored transitions against the box",
    )
    select.set_defaults(func=run_select)

    synth = benchmarks.add_parser(
        "synth", help="a seeded course of goals 1-20 m apart, synthesized, reported"
    )
    synth.add_argument(
        "--seconds",
        type=COURSE_SECONDS,
        default=600.0,
        help=f"length of the course ({COURSE_SECONDS.span}; default 600)",
    )
    synth.add_argument("--seed", type=SEED, default=1, help=f"random seed ({SEED.span}; default 1)")
    synth.add_argument("--profile", default="default", help="match profile (default: default)")
    synth.add_argument("--collection", help="draw snippets from this collection")
    synth.add_argument("--graph", help="choose among this transition graph's snippets only")
    synth.add_argument(
        "--data",
        help="bandai-2-dev/data, whose walks, turns and runs go into a fresh database "
        '(collection and graph "locomotion")',
    )
    synth.set_defaults(func=run_synth)

    compare = benchmarks.add_parser(
        "synth-compare",
        help="motion matching and a graph of models on the same courses, judged alike",
    )
    compare.add_argument("--collection", required=True, help="the collection both draw from")
    compare.add_argument(
        "--models",
        metavar="GRAPH",
        help="the graph of models (default: the collection's, built from its step models when "
        "there is none)",
    )
    compare.add_argument(
        "--seconds", type=COURSE_SECONDS, default=60.0, help="each course's length (default 60)"
    )
    compare.add_argument("--seed", type=SEED, default=0, help="the models' seed (default 0)")
    compare.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    compare.set_defaults(func=run_synth_compare)

    actions = benchmarks.add_parser(
        "actions",
        help="a hand meeting targets: each reach action of a graph of models over a grid fixed "
        "before tuning (the examples' peak box, 10-30 cm beyond it, out of reach), the character "
        "standing; errors after tree, refinement and IK, jumps, sliding, joint range, compute",
    )
    actions.add_argument("--models", metavar="GRAPH", required=True, help="the graph of models")
    actions.add_argument(
        "--actions",
        type=names,
        metavar="A,B",
        help="these reach actions only (default: every one of the graph's)",
    )
    actions.add_argument(
        "--groups",
        type=target_groups,
        metavar="G,H",
        help="these groups of targets only: inside, 10, 20, 30, out (default: all)",
    )
    actions.add_argument(
        "--seed", type=SEED, default=0, help="the standing piece's seed (default 0)"
    )
    actions.add_argument("--json", metavar="FILE", help="also write every target's figures as JSON")
    actions.set_defaults(func=run_actions)

    crowd = benchmarks.add_parser(
        "crowd",
        help="N simulated avatars against a primary and k hot standbys (a cluster of its own), "
        "and what k machines would serve",
    )
    crowd.add_argument(
        "--avatars", type=AVATARS, default=24, help=f"avatars ({AVATARS.span}; default 24)"
    )
    crowd.add_argument(
        "--standbys", type=STANDBYS, default=2, help=f"standbys ({STANDBYS.span}; default 2)"
    )
    crowd.add_argument(
        "--seconds", type=CROWD_SECONDS, default=60, help=f"{CROWD_SECONDS.span}; default 60"
    )
    crowd.add_argument(
        "--data",
        default="../shared/mocap/bandai-2-dev/data",
        help="Bandai dataset 2 BVH folder: its active walks and turns are loaded, its runs "
        "halfway (default ../shared/mocap/bandai-2-dev/data)",
    )
    crowd.add_argument(
        "--no-baseline",
        dest="baseline",
        action="store_false",
        help="with standbys, skip the baseline (the same avatars on the primary alone, on a "
        "cluster of its own, first in the same process), and its ratios",
    )
    crowd.set_defaults(func=run_crowd)

    mixed = benchmarks.add_parser(
        "mixed",
        help="REST writers, psql readers and avatars at once against the real modb serve, "
        "counted by the clients and held against the database (a cluster of its own)",
    )
    mixed.add_argument(
        "--seconds", type=MIXED_SECONDS, default=60, help=f"{MIXED_SECONDS.span}; default 60"
    )
    mixed.add_argument(
        "--writers", type=WRITERS, default=8, help=f"REST writers ({WRITERS.span}; default 8)"
    )
    mixed.add_argument(
        "--readers",
        type=READERS,
        default=8,
        help=f"pgbench readers of select_next_snippet ({READERS.span}; default 8)",
    )
    mixed.add_argument(
        "--avatars",
        type=MIXED_AVATARS,
        default=2,
        help=f"avatar pages over the WebSocket ({MIXED_AVATARS.span}; default 2)",
    )
    mixed.add_argument(
        "--clips",
        type=MIXED_CLIPS,
        default=12,
        help=f"Bandai walks loaded ({MIXED_CLIPS.span}; default 12); writers edit the first two "
        "together",
    )
    mixed.add_argument("--seed", type=SEED, default=1, help=f"random seed ({SEED.span}; default 1)")
    mixed.add_argument(
        "--data",
        default="../shared/mocap",
        help="the mocap folder, with bandai-2-dev/data and bandai-1/data (default ../shared/mocap)",
    )
    mixed.add_argument(
        "--in-database",
        action="store_true",
        help="run in the database --dsn names (it must have the modb_web role; what the run "
        "writes stays there) instead of a cluster of its own",
    )
    mixed.add_argument(
        "--postgres-log",
        metavar="FILE",
        help="with --in-database: that server's log, read for errors and deadlocks during the run",
    )
    mixed.set_defaults(func=run_mixed)

    scale = benchmarks.add_parser(
        "scale",
        help="select_next_snippet at several database sizes beside the flat query, numpy, a k-d "
        "tree",
    )
    scale.add_argument(
        "--sizes",
        type=sizes,
        default="10000,100000,all,1000000",
        help=f"snippet counts to measure at (1-{MAX_SIZE:,}), 'all' for the database itself; "
        "copies of the "
        "database (kept for the next run) with whole clips drawn up to a smaller count, or "
        "speed-resampled copies of its clips added up to a larger one (a million takes about "
        "half an hour to build, once)",
    )
    scale.add_argument(
        "--queries",
        type=QUERIES,
        default=200,
        help=f"number of seeded queries ({QUERIES.span}; default 200)",
    )
    scale.add_argument(
        "--baseline-queries",
        type=BASELINE_QUERIES,
        default=3,
        help="how many of the queries the flat sequential query (a) also answers (it takes "
        f"seconds to minutes each; {BASELINE_QUERIES.span}; default 3)",
    )
    scale.add_argument(
        "--pgbench-seconds",
        type=PGBENCH_SECONDS,
        default=10,
        help=f"length of each pgbench run ({PGBENCH_SECONDS.span}; default 10)",
    )
    scale.add_argument("--seed", type=SEED, default=1, help=f"random seed ({SEED.span}; default 1)")
    scale.add_argument("--profile", default="default", help="match profile (default: default)")
    scale.set_defaults(func=run_scale)

    tail = benchmarks.add_parser(
        "tail",
        help="select_next_snippet's tail on the user's path: p50 to max on each client path, first "
        "calls, pgbench, stages, every other selection kind without a graph and with one, "
        "exactness against the reference, bytes read per snippet",
    )
    tail.add_argument(
        "--sizes",
        type=sizes,
        default="100000,all,1000000",
        help="snippet counts to measure at, as for `bench scale` (default 100000,all,1000000)",
    )
    tail.add_argument(
        "--queries",
        type=TAIL_QUERIES,
        default=10_000,
        help=f"seeded requests per client path ({TAIL_QUERIES.span}; default 10000)",
    )
    tail.add_argument(
        "--exact",
        type=TAIL_EXACT,
        default=1000,
        help=f"requests compared with the reference function ({TAIL_EXACT.span}; default 1000)",
    )
    tail.add_argument(
        "--kinds",
        type=TAIL_EXACT,
        default=2000,
        help="requests for each other selection kind (k-best, exclusion, coming to rest, setting "
        f"off, annotations; each without a graph and with --graph's; {TAIL_EXACT.span}; "
        "default 2000, 0: none)",
    )
    tail.add_argument(
        "--graph",
        metavar="NAME|none",
        help="the transition graph each selection kind is also timed with (SET modb.graph; the "
        "previous snippets drawn from its snippets), rows labelled 'coming to rest, graph NAME', "
        "and the plain call with and without its cost-to-go (default: the database's newest "
        "transition graph, if it has one; none: without a graph only)",
    )
    tail.add_argument(
        "--pgbench-seconds",
        type=PGBENCH_SECONDS,
        default=10,
        help=f"length of each pgbench run ({PGBENCH_SECONDS.span}; default 10)",
    )
    tail.add_argument("--seed", type=SEED, default=1, help=f"random seed ({SEED.span}; default 1)")
    tail.set_defaults(func=run_tail)

    first_call = benchmarks.add_parser(
        "first-call",
        help="the first call of forward_kinematics, sample_motion and synthesize_from_models in a "
        "new session, the kernel pasted (0.23.0) or installed (the default version); two databases "
        "of the embedded cluster",
    )
    first_call.add_argument(
        "--data",
        default="../shared/mocap/bandai-2-dev/data",
        help="Bandai dataset 2 BVH folder: six active walks are loaded, their steps modelled "
        "(default ../shared/mocap/bandai-2-dev/data)",
    )
    first_call.add_argument(
        "--rounds",
        type=ROUNDS,
        default=20,
        help=f"new sessions per function and version ({ROUNDS.span}; default 20)",
    )
    first_call.set_defaults(func=run_first_call)


class BenchCommands:
    """The commands a benchmark runs to fill a database of its own (modb.bench.commands), each as
    `modb --dsn DSN ... --quiet` would run it: its messages, its errors, its exit status."""

    def load(self, dsn: str, files: Sequence[str], collection: str) -> int:
        return reporting_errors(
            lambda: load_paths(lambda: connect_to(dsn), files, collection, quiet=True)
        )

    def build_graph(self, dsn: str, name: str, collection: str) -> int:
        def build() -> int:
            with connect_to(dsn) as conn:
                return graph_command.build(conn, name, collection=collection, quiet=True)

        return reporting_errors(build)

    def annotate_steps(self, dsn: str, collection: str) -> int:
        return self._modb(dsn, "annotate", "--steps", collection, "--quiet")

    def build_model(self, dsn: str, name: str, collection: str, primitive: str) -> int:
        return self._modb(dsn, "model", "build", name, "--collection", collection, "--primitive",
                          primitive, "--quiet")  # fmt: skip

    def build_model_graph(self, dsn: str, name: str, collection: str) -> int:
        return self._modb(dsn, "model", "graph", name, "--collection", collection)

    def _modb(self, dsn: str, *argv: str) -> int:
        """`modb --dsn DSN ARGV` (annotate or model) run in this process; what it prints goes to
        stderr, beside the progress (a parser of those two: main's imports this module)."""
        from . import annotate, model

        parser = argparse.ArgumentParser(prog="modb")
        parser.add_argument("--dsn")
        parser.add_argument("-v", "--verbose", action="store_true")
        commands = parser.add_subparsers(dest="command", required=True)
        for command in (annotate, model):
            command.add_parser(commands)
        args = parser.parse_args(["--dsn", dsn, *argv])
        with contextlib.redirect_stdout(sys.stderr):
            return reporting_errors(lambda: args.func(args))


def run_first_call(args: argparse.Namespace) -> int:
    from modb.bench.first_call import report, run  # numpy (60 ms)

    try:
        result = run(
            Path(args.data),
            args.rounds,
            BenchCommands(),
            lambda text: print(f"modb bench first-call: {text}", file=sys.stderr),
        )
    except RuntimeError as e:
        print(f"modb bench first-call: {e}", file=sys.stderr)
        return 2
    print(report(result))
    return 0


def run_synth(args: argparse.Namespace) -> int:
    # numpy, scipy and synthesis on them (about 300 ms): not for `modb --help`
    from modb.bench.synth import locomotion_database, seeded_course
    from modb.synthesis.synth import report, synthesize

    from .synth_report import format_summary

    goals = seeded_course(args.seed, n_goals=int(args.seconds // 5) + 1)
    # A fresh database of the locomotion files in the embedded cluster, graph "locomotion" built.
    if args.data:
        args.dsn = locomotion_database(Path(args.data), BenchCommands())
        args.collection = "locomotion"
    with connect(args) as conn:
        settings = Settings(profile=args.profile, collection=args.collection, graph=args.graph)
        result = synthesize(conn, goals, args.seconds, settings)
        summary = format_summary(result, report(conn, result))
    graph = f", graph {args.graph}" if args.graph else ""
    print(
        f"seeded course (seed {args.seed}, goals 1-20 m apart), {args.seconds:g} s, "
        f"profile {args.profile}{graph}:"
    )
    print(summary)  # `modb synth --report` also lists every choice
    return 0


def run_synth_compare(args: argparse.Namespace) -> int:
    import json

    from modb.bench.synth_compare import run, table
    from modb.models import graphs

    from .synth import prepare_default_graph

    with connect(args) as conn:
        graph = args.models
        if graph is None:
            mine = [g for g in graphs.listing(conn) if g.data.get("collection") == args.collection]
            graph = mine[0].name if mine else graphs.build(conn, f"{args.collection} walk",
                                                           args.collection).name  # fmt: skip
        prepare_default_graph(conn, Settings(collection=args.collection), None, quiet=True)
        result = run(conn, args.collection, graph, args.seconds, args.seed)
    print(f"collection {args.collection}, graph of models {graph}, {args.seconds:g} s a course, "
          f"seed {args.seed}; the source's pose jump p99 "
          f"{result['source_pose_jump_p99_cm']:.1f} cm, pace {result['source_walking_speed']:.2f} "
          "m/s")  # fmt: skip
    print(table(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


def run_actions(args: argparse.Namespace) -> int:
    import json

    from modb.bench.actions import GROUP_NAMES, NoActions, run, table, wrapped  # the kernel

    groups = None if args.groups is None else [GROUP_NAMES[g] for g in args.groups]
    with connect(args) as conn:
        try:
            result = run(
                conn,
                args.models,
                args.actions,
                args.seed,
                groups,
                lambda text: print(f"modb bench actions: {text}", file=sys.stderr),
            )
        except NoActions as e:
            print(f"modb bench actions: graph {args.models}: {e}", file=sys.stderr)
            return 2
    intro = (
        f"graph of models {args.models}, seed {args.seed}: each reach action performed standing "
        "(its pelvis above the origin facing +Z), one synthesis a target; targets in the "
        "action's frame (metres); errors of the hand (the wrist; two hands: their RMS)"
    )
    print("\n".join(wrapped(intro)) + "\n")
    print(table(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2, default=float) + "\n")
    return 0


def run_crowd(args: argparse.Namespace) -> int:
    from modb.bench.crowd import against, report, run  # numpy and the Avatar (100 ms)

    def crowd_of(standbys: int):
        return run(
            Path(args.data),
            args.avatars,
            standbys,
            args.seconds,
            lambda text: print(f"modb bench crowd: {text}", file=sys.stderr),
            BenchCommands(),
        )

    try:
        baseline = crowd_of(0) if args.baseline and args.standbys else None
        crowd = crowd_of(args.standbys)
    except RuntimeError as e:
        print(f"modb bench crowd: {e}", file=sys.stderr)
        return 2
    print(report(crowd))
    if baseline is not None:
        print(f"\nbaseline, the primary alone:\n\n{report(baseline)}\n\n{against(crowd, baseline)}")
    return 0


def run_mixed(args: argparse.Namespace) -> int:
    try:
        from modb.bench.mixed import report, run  # httpx: the REST client of the test extras
    except ImportError as e:
        print(
            f"modb bench mixed: needs {e.name}: pip install -e '.[test]' (make setup does)",
            file=sys.stderr,
        )
        return 2
    try:
        result = run(
            Path(args.data),
            args.writers,
            args.readers,
            args.avatars,
            args.seconds,
            lambda text: print(f"modb bench mixed: {text}", file=sys.stderr),
            BenchCommands(),
            dsn=resolve(args.dsn)[0] if args.in_database else None,
            clips=args.clips,
            seed=args.seed,
            postgres_log=Path(args.postgres_log) if args.postgres_log else None,
        )
    except RuntimeError as e:
        print(f"modb bench mixed: {e}", file=sys.stderr)
        return 2
    print(report(result))
    return 0 if result.passed else 1


def run_scale(args: argparse.Namespace) -> int:
    from modb.bench.scale import bench_scale  # numpy and scipy (100 ms)
    from modb.bench.scale import report as scale_report

    print(
        f"modb bench scale: profile {args.profile}, {args.queries} seeded queries (seed "
        f"{args.seed}); "
        f"the flat query on the first {args.baseline_queries}",
        file=sys.stderr,
    )
    results = bench_scale(
        resolve(args.dsn)[0],
        args.sizes,
        args.queries,
        args.baseline_queries,
        args.seed,
        args.profile,
        args.pgbench_seconds,
        progress=lambda text: print(text, file=sys.stderr),
    )
    print("\n\n".join(scale_report(name, r) for name, r in results))
    return 0


def run_tail(args: argparse.Namespace) -> int:
    from modb.bench.tail import UnknownGraph, bench_tail, report  # numpy (60 ms)

    try:
        results = bench_tail(
            resolve(args.dsn)[0],
            args.sizes,
            args.queries,
            args.exact,
            args.kinds,
            args.seed,
            args.pgbench_seconds,
            progress=lambda text: print(text, file=sys.stderr),
            graph=args.graph,
        )
    except UnknownGraph as e:
        print(f"modb bench tail: {e}", file=sys.stderr)
        return 2
    print("\n\n".join(report(name, r) for name, r in results))
    return 0


def run_select(args: argparse.Namespace) -> int:
    from modb.bench.select import bench_select, bench_select_graph, report_graph  # numpy (60 ms)
    from modb.bench.select import report as select_report

    with connect(args) as conn:
        if args.graph:
            print(
                report_graph(
                    bench_select_graph(conn, args.queries, args.seed, args.profile, args.graph),
                    args.profile,
                    args.graph,
                )
            )
        else:
            print(
                select_report(
                    bench_select(conn, args.queries, args.seed, args.profile), args.profile
                )
            )
    return 0


def run_load(args: argparse.Namespace) -> int:
    from modb.bench.load import bench_load, bench_parse, report  # numpy and the loader (150 ms)

    folder = Path(args.data or "../shared/mocap/bandai-1")
    files = sorted(folder.rglob("*.bvh"))
    if not files:
        print(f"modb bench load: no .bvh files under {folder}", file=sys.stderr)
        return 2
    try:
        import bvhio  # the baseline; an optional dependency, so looked for only here
    except ImportError:
        print(
            "modb bench load: needs bvhio as the baseline: pip install -e '.[test]' (make setup "
            "does)",
            file=sys.stderr,
        )
        return 2
    del bvhio  # only its presence is checked here; modb.bench.load imports it
    if args.dsn:
        admin, make_dsn = (
            args.dsn,
            lambda name: psycopg.conninfo.make_conninfo(args.dsn, dbname=name),
        )
    else:
        cluster = Cluster.default()
        cluster.start()
        admin, make_dsn = cluster.dsn("postgres"), cluster.dsn
    parse = bench_parse(files, args.rounds)
    load = bench_load(files, args.rounds, admin, make_dsn)
    print(report(folder, parse, load))
    return 0
