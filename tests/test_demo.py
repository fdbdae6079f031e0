"""`modb demo`: real capture into the database, from the shared data or, on a fresh clone, from
PyPI; and what its report says of goals not reached."""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from support import shared
from support.bvh_oracle import bvhio_world_positions
from support.commands import run_modb
from support.data import CMU_UNITS

from modb.cli.demo_run import COURSE
from modb.cli.synth_report import format_summary
from modb.database.connection import connect
from modb.demo.data import WALKING
from modb.demo.runs import StepClips
from modb.loader.bvh import read_bvh
from modb.synthesis.chain import Choice
from modb.synthesis.placement import Placement
from modb.synthesis.quality import Report, goal_reach
from modb.synthesis.synth import Synthesis

REACH = "goals >= 5 m reached within 2x straight line"


def _half_second(step: int, goal: int, where: Placement, reached: bool = False) -> Choice:
    """A 0.5 s snippet at 30 fps serving `goal` of the demo's course, placed at `where`."""
    return Choice(
        step=step,
        snippet_id=100 + step,
        clip_id=1,
        version=1,
        mirrored=False,
        first_frame=15 * step,
        n_frames=16,
        fps=30.0,
        start_frame=15 * step,
        end_frame=15 * step + 15,
        placement=where,
        end=where,
        goal=goal,
        target=COURSE[goal - 1],
        reached=reached,
        relax_level=0,
        continuity=0.0,
        proximity=0.0,
        latency_ms=1.0,
        waited_ms=0.0,
    )


def _report_of(chain: list[Choice]) -> tuple[Report, str]:
    figures = dict.fromkeys(
        ["seconds", "natural_share_over_one", "natural_r_p999", "seam_share_over_one"], 0.0
    )
    figures |= dict.fromkeys(["seam_r_p99", "recombination", "last_level_share"], 0.0)
    rep = Report(
        **figures,
        snippets=len(chain),
        natural_steps=1,
        seams=0,
        levels={0: len(chain)},
        latency_ms_p50=1.0,
        latency_ms_p99=1.0,
        walking_speed=0.81,
        goals=goal_reach(chain, COURSE, walking_speed=0.81),
    )
    return rep, format_summary(Synthesis(None, chain, list(COURSE)), rep)


# The fresh-clone demo before 0.17.0, on CMU 01_01 alone: goal 1 (8 m ahead) reached in 12 s, then
# goal 2 behind the avatar for the remaining 48 s, never reached, and goals 3-6 never current. Its
# report said the reach aim was met.
def test_the_report_counts_goals_not_reached_and_never_current_as_missed():
    start, at_goal_1 = Placement((0.0, 0.9, 0.0), 0.0), Placement((0.0, 0.9, 8.0), -math.pi / 2)
    chain = [_half_second(k, 1, start, reached=k == 23) for k in range(24)]
    chain += [_half_second(k, 2, at_goal_1) for k in range(24, 120)]
    rep, text = _report_of(chain)
    assert rep.aims[REACH] is False
    assert f"{REACH}: NOT met (1 of 6 goals reached)" in text
    assert "goal 2 (8, 8): 8.0 m behind, straight 9.9 s, took not reached (missed" in text
    assert "goals 3-6: never became current (missed" in text


@pytest.mark.parametrize("steps", [26, 120])
def test_a_goal_the_strip_ended_on_is_judged_once_it_had_twice_the_straight_line(steps):
    # Goal 2, 8 m ahead of where goal 1 was reached: 9.9 s straight. After 1 s the strip's end cut
    # it short (not judged, nor the goals after it); after 48 s it is missed, and so are they.
    start, at_goal_1 = Placement((0.0, 0.9, 0.0), 0.0), Placement((0.0, 0.9, 8.0), math.pi / 2)
    chain = [_half_second(k, 1, start, reached=k == 23) for k in range(24)]
    chain += [_half_second(k, 2, at_goal_1) for k in range(24, steps)]
    rep, text = _report_of(chain)
    if steps == 26:
        assert rep.aims[REACH] is True
        assert f"{REACH}: met (1 of 1 goals reached; 5 more not judged: " in text
        assert "goals 3-6: never became current (not judged: the strip ended first)" in text
    else:
        assert rep.aims[REACH] is False and f"{REACH}: NOT met (1 of 6 goals reached)" in text


def test_demo_with_the_shared_data(locomotion, tmp_path):
    """The demo as conftest's `locomotion` fixture ran it on ../shared/mocap (its database is that
    fixture's): what it printed, loaded and wrote."""
    if os.environ.get("MODB_TEST_LOCOMOTION_DSN"):
        pytest.skip("MODB_TEST_LOCOMOTION_DSN: the demo was not run in this test run")
    demo = shared.kept("demo")
    stdout, stderr = demo["stdout"], demo["stderr"]
    assert "demo/cmu/131" in stdout and "demo/bandai-2/locomotion" in stdout
    assert "The other family (statistical motion models) left out: --no-models." in stdout
    with connect(locomotion) as db:  # (other modules add clips of their own outside demo/)
        (clips,) = db.execute(
            "SELECT count(*) FROM modb.current_clips WHERE collection LIKE 'demo/%'"
        ).fetchone()
    assert clips == 1 + 14 + 419  # CMU 01_01, CMU 131, and Bandai dataset 2's walks, turns and runs
    assert "seam roughness" in stdout and "goal reach" in stdout
    assert "aims:" in stdout and "NOT met" not in stdout and "Not met" not in stdout, stderr
    strip = read_bvh(str(Path(demo["cache"]) / "synthesized.bvh"))
    assert (strip.n_frames - 1) / strip.fps >= 60.0 and strip.fps == 30.0
    # Then the first thing a user runs, with no other flag (issue 24): the largest pool, the demo's
    # graph, root motion; every goal reached, no pose jump past the sources' p99.9, no root jump.
    out, report = tmp_path / "w.bvh", tmp_path / "w.json"
    synth = ["synth", "--to", "3,0", "--to", "3,3", "--to", "0,4", "--seconds", "40"]
    r = run_modb(locomotion, *synth, "--out", out, "--report-json", report)
    assert r.returncode == 0, r.stderr
    assert "drawing from collection demo/bandai-2/locomotion" in r.stderr
    assert "building" not in r.stderr and "no current transition graph" not in r.stderr
    figures = json.loads(report.read_text())["report"]
    assert [g["reached"] for g in figures["goals"]] == [True, True, True]
    assert figures["pose_jump_max"] <= figures["natural_pose_jump_p999"]
    names, positions = bvhio_world_positions(str(out), strip.skeleton.unit_m)
    top = positions[:, names.index("joint_Root")]
    assert (
        np.linalg.norm(np.diff(top, axis=0), axis=1).max() < 0.05 and np.abs(top[:, 1]).max() < 1e-6
    )


def test_the_demos_family_learns_the_walks_and_turns_and_leaves_the_runs_out(locomotion):
    """The clips the demo's family of motion models learns from, in the demo's database (the
    shared run left its models half out: nothing is annotated yet), and what the demo says of the
    runs (docs/models.md, "Runs and the family")."""
    with connect(locomotion) as db:
        clips = StepClips.of(db, "demo/bandai-2/locomotion")
        names = dict(db.execute("SELECT clip_id, name FROM modb.current_clips").fetchall())
    # Bandai dataset 2's 72 walks, 111 left and 108 right walk-turns; its 128 runs
    assert (len(clips.walking), clips.runs, clips.runs_annotated) == (72 + 111 + 108, 128, 0)
    assert clips.to_annotate == clips.walking
    assert all(names[c].split("_")[1] in WALKING for c in clips.walking)
    line = clips.runs_line("demo/bandai-2/locomotion")
    assert line.startswith("runs: the 128 runs of demo/bandai-2/locomotion are left out of the")


def test_demo_on_a_fresh_clone_downloads_cmu_01_01(fresh_db, db, tmp_path):
    r = run_modb(fresh_db, "demo", "--data", tmp_path / "absent", "--cache", tmp_path / "cache")
    assert r.returncode == 0, r.stderr
    assert "using CMU trial 01_01 from PyPI" in r.stdout
    assert sorted(p.name for p in (tmp_path / "cache" / "cmu-01").iterdir()) == [
        "01.asf",
        "01_01.amc",
    ]
    row = db.execute("SELECT name, n_frames, fps, collection FROM modb.current_clips").fetchone()
    # CMU_data.csv: trial 01_01 runs at 120 fps; the AMC holds 2751 frames.
    assert row == ("01_01", 2751, 120.0, "demo/cmu/01")
    strip = read_bvh(str(tmp_path / "cache" / "synthesized.bvh"), units=CMU_UNITS)
    assert (strip.n_frames - 1) / strip.fps >= 60.0 and strip.fps == 120.0
    # The take jumps ahead and turns around but never turns to the side: the course is one it can
    # walk, the output says why, and every goal is reached and every aim met.
    assert "never turns to the side: the course goes 8 m ahead, back and ahead again" in r.stdout
    assert "through the goals (0, 8), (0, 0), (0, 8) " in r.stdout
    assert f"{REACH}: met (3 of 3 goals reached)" in r.stdout
    assert "NOT met" not in r.stdout, r.stdout[-2000:]
    # Then the other family on the same take (issue 62): its steps annotated and the graph of models
    # built (as jobs where the database runs them); the course walked from it, its report, and both
    # judged side by side
    assert "graph of models demo (seed 0): " in r.stdout, f"no models' report: {r.stdout[-2000:]}"
    models, _, table = r.stdout.split("graph of models demo (seed 0): ")[1].partition("| figure |")
    assert table, f"no comparison table: {models[-2000:]}"
    assert f"aim met: {REACH}" in models and "constraint error, median: " in models
    assert "Not met on the data of demo/cmu/01: " in models and "least a model takes" in models
    assert table.startswith(" demo: MM | demo: models |\n")
    assert "| goals reached | 3 of 3 | 3 of 3 |" in table and "| novelty, median / p95" in table
    assert (tmp_path / "cache" / "synthesized-models.bvh").is_file()
    # what a second run keeps (a test database has no job tables: both ran in the demo's process)
    assert StepClips.of(db, "demo/cmu/01").to_annotate == []
    current = db.execute(
        "SELECT primitive FROM modb.model_status WHERE name LIKE %s AND latest AND stale IS NULL",
        ["demo\\_%"],
    ).fetchall()
    assert {"left_step", "right_step"} <= {p for (p,) in current}, current
