"""`modb demo`, its second half: the other synthesis family on the same data and course. The steps
of the collection's walks are annotated (`modb annotate --steps`), its family graph of statistical
motion models built (`modb model graph`), both as jobs where the database runs them, the course
walked from the models (`modb synth --models`), and both families judged alike (`modb bench
synth-compare`'s table). What is built is kept from one run of the demo to the next."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import psycopg
from psycopg.rows import dict_row

from modb.bench import synth_compare
from modb.bvh_export import write_bvh_file
from modb.demo import MODEL_GRAPH
from modb.demo.runs import StepClips
from modb.models import family
from modb.models.examples import NoExamples
from modb.models.graphs import GraphError
from modb.synthesis.from_models import Source, measure, synthesize
from modb.synthesis.root_motion import with_root_motion
from modb_kernel.processed import MIN_EXAMPLES

from .annotate import find_steps, totals
from .model import family_graph
from .synth_report import format_model_report

SEED = 0  # the walk's choices: the same seed, the same walk (modb synth --models's default)
BVH = "synthesized-models.bvh"


class FamilyNotBuilt(Exception):
    """The family cannot be built on this data (too few steps, a job queued or failed): why."""


def _as_command(args: argparse.Namespace, collection: str) -> argparse.Namespace:
    """The options `modb annotate --steps` and `modb model graph` would get: wait for the jobs,
    with progress, the family's defaults."""
    return argparse.Namespace(dsn=args.dsn, background=False, after=None, quiet=False,
                              collection=collection, model=None, seed=0)  # fmt: skip


def _clips(n: int) -> str:
    return f"{n} clip{'' if n == 1 else 's'}"


def _steps(conn: psycopg.Connection, command: argparse.Namespace, collection: str) -> None:
    clips = StepClips.of(conn, collection)
    if not clips.walking:
        print(f"  no clip to find steps in{', but runs' if clips.runs else ''}")
    elif not clips.to_annotate:
        print(f"  the steps of {_clips(len(clips.walking))}: annotated already")
    else:
        print(f"  finding the steps of {_clips(len(clips.to_annotate))} (modb annotate --steps)...")
        found = find_steps(conn, command, clips.to_annotate)
        if isinstance(found, int):
            raise FamilyNotBuilt("the steps were not annotated (said above)")
        print(f"  {totals(found)}")
    if line := clips.runs_line(collection):
        print(f"  {line}")


def _enough_steps(conn: psycopg.Connection, collection: str) -> None:
    """Refuses, saying why, a collection whose steps are too few for the graph's two step models
    (their own and, where the skeleton mirrors, the other foot's)."""
    with conn.cursor(row_factory=dict_row) as cur:
        segments = cur.execute(family.SEGMENTS, [collection, list(family.FAMILY)]).fetchall()
    counts = family.examples(family.of_the_steps_skeleton(segments)[0])
    few = {p: counts[p] for p in ("left_step", "right_step") if counts[p] < MIN_EXAMPLES}
    if few:
        found = " and ".join(f"{n} {p} example{'' if n == 1 else 's'}" for p, n in few.items())
        raise FamilyNotBuilt(f"{collection} gives {found}; a model needs at least {MIN_EXAMPLES}")


def _family(conn: psycopg.Connection, command: argparse.Namespace) -> None:
    try:
        made = family_graph(conn, command, MODEL_GRAPH)
    except (GraphError, NoExamples) as e:  # built here, refused (a job's refusal is said above)
        raise FamilyNotBuilt(str(e)) from None
    except psycopg.Error as e:
        raise FamilyNotBuilt(e.diag.message_primary or str(e)) from None
    if isinstance(made, int):
        raise FamilyNotBuilt("the family's job did not finish (said above)")
    for line in family.summary(made):
        print(f"  {line}")


def _walk(conn: psycopg.Connection, course, seconds: float, cache: Path
          ) -> tuple[synth_compare.Walked, dict, dict]:  # fmt: skip
    """The course walked from the graph of models: the strip and its time, the quality figures
    (as `modb synth --models --report` measures them), the server's report."""
    t = time.perf_counter()
    strip = synthesize(conn, MODEL_GRAPH, course, seconds, SEED)
    walked = synth_compare.Walked(strip.motion, time.perf_counter() - t)
    write_bvh_file(with_root_motion(strip.motion), cache / BVH)
    return walked, measure(strip, Source.of(conn, MODEL_GRAPH)), strip.report


def show_models(
    conn: psycopg.Connection,
    args: argparse.Namespace,
    collection: str,
    course: list[tuple[float, float]],
    seconds: float,
    matched: synth_compare.Walked,
    why_unmet: str,
) -> bool:
    """The second half of the demo, printed; `matched` is the first half's strip (motion matching
    on the same course). False when the family could not be built here (said in one line)."""
    cache = Path(args.cache)
    command = _as_command(args, collection)
    print(
        f"\nThe other family: statistical motion models of the steps of {collection} "
        "(docs/models.md), kept from one run of the demo to the next. A first run builds a model "
        "per primitive, about 20 s for thousands of steps (as jobs where the database runs them: "
        "`modb jobs list`)..."
    )
    try:
        _steps(conn, command, collection)
        _enough_steps(conn, collection)
        print(f"  graph of models {MODEL_GRAPH} (modb model graph {MODEL_GRAPH} --collection "
              f"{collection})...")  # fmt: skip
        _family(conn, command)
    except FamilyNotBuilt as e:
        print(f"No graph of models here: {e}; the demo goes on without it.")
        return False
    goals = ", ".join(f"({x:g}, {z:g})" for x, z in course)
    print(f"\nWalking the same course, {goals}, on the graph of models {MODEL_GRAPH} (seed {SEED}; "
          f"modb synth --models {MODEL_GRAPH})...")  # fmt: skip
    modelled, figures, report = _walk(conn, course, seconds, cache)
    print(format_model_report(figures, report))
    unmet = [aim for aim, met in figures["aims"].items() if met is False]
    if unmet:
        print(f"\nNot met on the data of {collection}: {'; '.join(unmet)}. {why_unmet}")
    print(f"\nBoth families on this course, judged alike against the capture of {collection} "
          "(modb bench synth-compare's table; MM: motion matching)...")  # fmt: skip
    source = synth_compare.Source.of(conn, collection)
    result = synth_compare.result(source, collection, MODEL_GRAPH, seconds, SEED)
    result["courses"]["demo"] = synth_compare.compared(course, matched, modelled, source)
    print(synth_compare.table(result))
    print(f"(`modb bench synth-compare --collection {collection} --models {MODEL_GRAPH}` walks two "
          f"more courses, right angles and about-turns; wrote {cache / BVH})")  # fmt: skip
    return True
