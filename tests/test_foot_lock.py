"""Foot locking (issue 24): on synthesized strips of Bandai's rig and CMU's, standing feet slide
less by the test's own measure (scipy's kinematics), the seams are no rougher, and nothing but the
legs moves: the pelvis, trunk and arms keep their world positions and each foot its world
orientation."""

from __future__ import annotations

import json

import numpy as np
from support.commands import run_modb
from support.snippet_oracle import motion_world

from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.foot_lock import lock_feet
from modb.synthesis.quality import NaturalSteps, measure
from modb.synthesis.synth import source_motions, synthesize

COURSE = [(0.0, 4.0), (4.0, 4.0), (4.0, 0.0), (0.0, 0.0)]


def skating(motion) -> float:
    """Mean horizontal speed (m/s) of ankles and toes in the frames where each is within 2 cm of its
    own 2nd-percentile height and rises or sinks slower than 0.15 m/s, central differences:
    computed here from scipy's kinematics."""
    sk = motion.skeleton
    positions, _ = motion_world(motion)
    speeds = []
    for side in ("left", "right"):
        for part in ("ankle", "toe"):
            p = positions[:, sk.index(sk.joint_map[f"{side}_{part}"])]
            speed = np.linalg.norm((p[2:] - p[:-2])[:, [0, 2]], axis=1) * motion.fps / 2
            rising = np.abs(p[2:, 1] - p[:-2, 1]) * motion.fps / 2
            standing = (p[1:-1, 1] <= np.percentile(p[:, 1], 2) + 0.02) & (rising < 0.15)
            speeds.append(speed[standing])
    return float(np.concatenate(speeds).mean())


def leg_subtrees(sk) -> set[int]:
    """Every joint at or below either hip."""
    hips = {sk.index(sk.joint_map[f"{side}_hip"]) for side in ("left", "right")}
    below = set()
    for k, parent in enumerate(sk.parents):
        if k in hips or parent in below:
            below.add(k)
    return below


def check_foot_lock(conn, result, least_drop: float) -> None:
    strip = result.strip
    locked = lock_feet(strip)
    sk = strip.skeleton
    before, turned_before = motion_world(strip)
    after, turned_after = motion_world(locked)
    rest = [k for k in range(len(sk.joints)) if k not in leg_subtrees(sk)]
    assert np.abs(after[:, rest] - before[:, rest]).max() < 1e-9
    for side in ("left", "right"):
        foot = sk.index(sk.joint_map[f"{side}_ankle"])
        change = (turned_after[foot] * turned_before[foot].inv()).magnitude()
        assert change.max() < 1e-6, (side, change.max())
    drop = 1 - skating(locked) / skating(strip)
    assert drop >= least_drop, (skating(strip), skating(locked))
    natural = NaturalSteps.of(source_motions(conn, result.chain[0].snippet_id, result.collection))
    plain = measure(strip, result.chain, result.goals, natural, 1.0)
    held = measure(locked, result.chain, result.goals, natural, 1.0)
    assert held.seam_share_over_one <= plain.seam_share_over_one
    assert held.seam_r_p99 <= plain.seam_r_p99 * 1.001
    assert held.pose_jump_max <= plain.pose_jump_max + 0.002  # metres: Bandai's rises 1 mm


def test_foot_lock_on_bandai(locomotion):
    with connect(locomotion) as conn:
        check_foot_lock(conn, synthesize(conn, COURSE, 30.0, Settings()), least_drop=0.05)


def test_foot_lock_on_cmu(cmu):
    with connect(cmu) as conn:
        result = synthesize(conn, COURSE, 20.0, Settings(graph="none", collection="cmu/131"))
        check_foot_lock(conn, result, least_drop=0.2)


def test_synth_foot_lock_reports_less_skating(locomotion, tmp_path):
    figures = {}
    for flag in ([], ["--foot-lock"]):
        report = tmp_path / f"report{len(flag)}.json"
        args = ["--to", "0,4", "--to", "4,4", "--seconds", "15", "-q"]
        r = run_modb(
            locomotion, "synth", *args, *flag, "--out", tmp_path / "w.bvh", "--report-json", report
        )
        assert r.returncode == 0, r.stderr
        figures[bool(flag)] = json.loads(report.read_text())["report"]
    assert figures[True]["foot_skating"] < 0.95 * figures[False]["foot_skating"]
    assert figures[True]["natural_foot_skating"] == figures[False]["natural_foot_skating"] > 0
    assert figures[True]["seam_share_over_one"] <= figures[False]["seam_share_over_one"]
