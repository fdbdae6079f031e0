"""Starts, stops, idle and turning steps (issue 60) found by the kernel (modb_kernel.primitives) on
the shipped capture, against the test's own detection: its own forward kinematics (scipy's
rotations), contacts (support.own_steps), speeds, runs and headings; and against what the data is
known to hold (the shipped data's README and the issue's measurements): CMU 16 starts from
standing in 16_31 and 16_32 and stops in 16_33, 16_34 and its two runs, and never idles; Bandai
dataset 2's walks never start, stop or stand; Bandai dataset 1's bows stand still before and
after; a held reach (Bandai's raise-hand) is no idle."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from support import own_kinematics
from support.data import mocap
from support.own_steps import SIDES, own_cleanup, own_contacts, own_steps, own_touchdowns

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb_kernel import primitives as kernel_primitives

TURN_DEGREES = 20.0  # the documented threshold: a step turning more is a turning step


def own_speed(points, fps, span=0.1):
    """|velocity| over about span seconds, by differences of frames k apart at each side."""
    k = max(1, round(span * fps / 2))
    padded = np.concatenate([np.repeat(points[:1], k, 0), points, np.repeat(points[-1:], k, 0)])
    moved = np.linalg.norm(padded[2 * k :] - padded[: -2 * k], axis=-1)
    n = len(points)
    span_frames = np.minimum(np.arange(n) + k, n - 1) - np.maximum(np.arange(n) - k, 0)
    return moved / np.maximum(span_frames, 1) * fps


def own_runs(flags):
    out, k = [], 0
    for value, group in itertools.groupby(flags):
        n = len(list(group))
        if value:
            out.append((k, k + n))
        k += n
    return out


def own_primitives(motion, reach_is_idle=False):
    """{(name, start, end)} by the rules docs/primitives.md states, computed here (reach_is_idle:
    without the rule that a wrist above its shoulder is no idle)."""
    sk, fps = motion.skeleton, motion.fps
    p = own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, motion.rotations,
                                       motion.translations)  # fmt: skip
    at = {k: sk.names.index(v) for k, v in sk.joint_map.items() if v in sk.names}
    contact = own_contacts(motion)
    pelvis = p[:, at["pelvis"]]
    slow = own_speed(pelvis * [1.0, 0.0, 1.0], fps) < 0.15
    calm = np.ones(len(p), dtype=bool)
    for j in ("left_wrist", "right_wrist", "head"):
        calm &= own_speed(p[:, at[j]] - pelvis, fps) < 0.15
    for side in SIDES:
        calm &= reach_is_idle | (p[:, at[f"{side}_wrist"], 1] < p[:, at[f"{side}_shoulder"], 1])
    standing = own_cleanup(list(contact["left"] & contact["right"] & slow), fps)
    found = set()
    steps = own_steps(contact, fps)
    found |= set(steps)
    axis = p[:, at["left_hip"]] - p[:, at["right_hip"]]
    heading = np.arctan2(-axis[:, 2], axis[:, 0])

    def turned(a, b):
        return (heading[b] - heading[a] + np.pi) % (2 * np.pi) - np.pi

    for k, (name, a, b) in enumerate(steps):
        halves = []
        if k > 0 and steps[k - 1][2] == a:
            halves.append(turned(steps[k - 1][1], b) / 2)
        if k + 1 < len(steps) and steps[k + 1][1] == b:
            halves.append(turned(a, steps[k + 1][2]) / 2)
        if halves and abs(np.degrees(np.mean(halves))) > TURN_DEGREES:
            found.add((name.replace("_step", "_turning_step"), a, b))
    down = sorted((t, s) for s in SIDES for t in own_touchdowns(contact[s]))
    for first, past in own_runs(standing):
        after = [(t, s) for t, s in down if t > past]
        if after:
            t, side = after[0]
            if not contact[side][past : t].all() and (t - (past - 1)) / fps <= 2.0:
                found.add((f"{side}_start", past - 1, t))
        before = [(t, s) for t, s in down if t < first]
        if len(before) >= 2:
            (last, side), (planted, other) = before[-1], before[-2]
            swing, settle = (last - planted) / fps, (first - last) / fps
            if other != side and 0.2 <= swing <= 1.5 and 0 < settle <= 2:
                found.add((f"{side}_stop", planted, first))
    for first, past in own_runs(standing & calm):
        seconds = (past - first) / fps
        if seconds >= 0.5:
            cuts = np.linspace(first, past - 1, max(1, round(seconds)) + 1).round().astype(int)
            found |= {("idle", int(a), int(b)) for a, b in zip(cuts, cuts[1:])}
    return found


def kernel_found(motion):
    sk = motion.skeleton
    return kernel_primitives.find(sk.parents, sk.offsets, motion.rotations, motion.translations,
                                  sk.translated, sk.names, sk.joint_map, motion.fps)  # fmt: skip


def matched(kernel, oracle, slack=2):
    """Kernel primitives without an oracle one of the same name within slack frames at both ends,
    and the other way round."""
    def near(a, pool):
        return any(b[0] == a[0] and abs(b[1] - a[1]) <= slack and abs(b[2] - a[2]) <= slack
                   for b in pool)  # fmt: skip
    return [a for a in kernel if not near(a, oracle)], [b for b in oracle if not near(b, kernel)]


@pytest.fixture(scope="module")
def cmu16():
    asf = read_asf(str(mocap("cmu", "16", "16.asf")))
    return {p.stem: read_amc(str(p), asf) for p in sorted(mocap("cmu", "16").glob("16_*.amc"))}


def bandai(folder, pattern, n=None):
    return [read_bvh(str(p)) for p in sorted(mocap(folder, "data").glob(pattern))[:n]]


def test_cmu16_starts_stops_and_turns_as_the_data_holds_them(cmu16):
    found = {}
    for trial, motion in cmu16.items():
        kernel = [(n, a, b) for n, a, b, _ in kernel_found(motion)]
        extra, missing = matched(kernel, own_primitives(motion))
        assert extra == [] and missing == [], (trial, extra, missing)
        found[trial] = kernel
    kinds = {t: {n for n, _, _ in f if not n.endswith("_step")} for t, f in found.items()}
    # the two starts from standing: the left foot leaves first in both
    assert kinds["16_31"] == {"left_start"} and kinds["16_32"] == {"left_start"}
    assert {t for t, k in kinds.items() if any(n.endswith("_stop") for n in k)} == {
        "16_08", "16_33", "16_34", "16_57"}  # fmt: skip
    assert not any("idle" in k for k in kinds.values())  # no half second of standing still
    turning = {t for t, f in found.items() if any("turning" in n for n, _, _ in f)}
    assert {"16_17", "16_18", "16_19", "16_20", "16_27", "16_28", "16_29", "16_30"} <= turning
    assert not {"16_15", "16_16", "16_21", "16_22"} & turning  # straight walks


def test_a_start_leads_into_a_step_and_a_stop_follows_one(cmu16):
    """Keyframes as the graph joins them: a left_start ends at the left foot's touchdown, where a
    right_step begins; a stop begins at a step's end and its middle keyframe is the last
    touchdown."""
    for trial in ("16_31", "16_32", "16_33", "16_34"):
        found = kernel_found(cmu16[trial])
        steps = {(a, b): n for n, a, b, _ in found if n in ("left_step", "right_step")}
        for name, a, b, keys in found:
            if name.endswith("_start"):
                side = name.split("_")[0]
                assert keys[0] == a and keys[-1] == b and a < keys[1] < b
                follow = [n for (s, _), n in steps.items() if s == b]
                assert follow == [f"{'right' if side == 'left' else 'left'}_step"], (trial, found)
            if name.endswith("_stop"):
                assert any(e == a for (_, e) in steps), (trial, found)
                assert keys[0] == a and keys[-1] == b and a < keys[1] < b


def test_bandai_walks_hold_no_start_stop_or_standing_and_turns_only_where_they_turn():
    walks = bandai("bandai-2-dev", "dataset-2_walk_active_0*.bvh", 6)
    turns = bandai("bandai-2-dev", "dataset-2_walk-turn-left_active_0*.bvh", 6)
    for motion in walks + turns:
        kernel = [(n, a, b) for n, a, b, _ in kernel_found(motion)]
        extra, missing = matched(kernel, own_primitives(motion))
        assert extra == [] and missing == [], (motion.name, extra, missing)
        names = {n for n, _, _ in kernel}
        assert names <= {"left_step", "right_step", "left_turning_step", "right_turning_step"}
        if motion in walks:
            assert not any("turning" in n for n in names), motion.name
    assert sum(any("turning" in n for n, *_ in kernel_found(m)) for m in turns) >= 4


def test_bows_stand_idle_and_a_held_reach_does_not():
    bows = bandai("bandai-1", "dataset-1_bow_*.bvh")
    idle_clips = 0
    for motion in bows:
        kernel = [(n, a, b) for n, a, b, _ in kernel_found(motion)]
        extra, missing = matched(kernel, own_primitives(motion))
        assert extra == [] and missing == [], (motion.name, extra, missing)
        pieces = [(a, b) for n, a, b in kernel if n == "idle"]
        idle_clips += bool(pieces)
        for a, b in pieces:
            assert 0.5 <= (b - a + 1) / motion.fps <= 1.6, (motion.name, a, b)
    assert idle_clips >= 10, idle_clips
    held = 0
    for motion in bandai("bandai-2-dev", "dataset-2_raise-up-*_active_0*.bvh"):
        assert not [p for p in kernel_found(motion) if p[0] == "idle"], motion.name
        held += any(n == "idle" for n, _, _ in own_primitives(motion, reach_is_idle=True))
    assert held >= 10, held  # reaches held still for half a second: the rule is what refuses them
