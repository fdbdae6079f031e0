"""Actions done standing found from the motion (issue 63): `modb annotate --action NAME`,
modb.annotate_action, its REST endpoints and job, on Bandai's hand actions.

Checked against the test's own computations with its own forward kinematics (scipy's rotations):
which hand acts from the clip's file name, a reach's keyframe as the middle of the plateau within
1 cm of the wrist's (or wrists' mean) highest point found by brute force, a wave's first and last
turn by scipy's find_peaks on the wrist's sideways and vertical motion relative to the hips. A clip
made here by holding a raise's first and last frames for a second gets a standing lead-in and
lead-out; one holding a single frame is refused.

The `modb` command runs in this process (`process=False`)."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import psycopg
import pytest
from scipy.signal import find_peaks
from support.commands import run_modb_here as modb
from support.data import mocap
from support.databases import scratch_database
from support.own_kinematics import world_positions

from modb.bvh_export import write_bvh_file
from modb.clips import read_motion
from modb.database.connection import connect
from modb.loader.bvh import read_bvh

HOLD = 30  # frames each end of the held clip is held (1 s at Bandai's 30 fps)
SIDES = ("left", "right")


def clips_of(action: str, count: int) -> list:
    files = sorted(mocap("bandai-2-dev", "data").glob(f"dataset-2_{action}_active_*.bvh"))
    assert len(files) >= count, action
    return files[:: max(1, len(files) // count)][:count]


def own_positions(motion) -> tuple[np.ndarray, dict[str, int]]:
    sk = motion.skeleton
    at = world_positions(sk.parents, sk.offsets, sk.translated, motion.rotations,
                         motion.translations)  # fmt: skip
    return at, {k: sk.names.index(v) for k, v in sk.joint_map.items() if v in sk.names}


def own_plateau_middle(motion, hands) -> int:
    """The middle of the frames around the highest within 1 cm of it, by brute force."""
    at, index = own_positions(motion)
    height = np.mean([at[:, index[f"{s}_wrist"], 1] for s in hands], axis=0)
    top = max(range(len(height)), key=lambda t: height[t])
    first = top
    while first > 0 and height[first - 1] >= height[top] - 0.01:
        first -= 1
    last = top
    while last + 1 < len(height) and height[last + 1] >= height[top] - 0.01:
        last += 1
    return (first + last) // 2


def own_wave_span(motion, hands) -> tuple[int, int]:
    """The first and last turn of the wave: extremes of the wrist relative to the pelvis, sideways
    (along the hips) and up, that stand out by at least 10 cm (scipy's find_peaks)."""
    at, index = own_positions(motion)
    across = at[:, index["left_hip"]] - at[:, index["right_hip"]]
    across[:, 1] = 0
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    firsts, lasts = [], []
    for side in hands:
        rel = at[:, index[f"{side}_wrist"]] - at[:, index["pelvis"]]
        for signal in (np.sum(rel * across, axis=1), rel[:, 1]):
            turns = sorted(np.r_[find_peaks(signal, prominence=0.1)[0],
                                 find_peaks(-signal, prominence=0.1)[0]])  # fmt: skip
            if len(turns) >= 4:
                firsts.append(turns[0])
                lasts.append(turns[-1])
    return min(firsts), max(lasts)


def hands_by_name(path) -> list[str]:
    if "both" in path.name:
        return ["left", "right"]
    return ["right" if "right" in path.name else "left"]


def kernel_action(motion):
    from modb_kernel import actions

    sk = motion.skeleton
    return actions.find(sk.parents, sk.offsets, motion.rotations, motion.translations,
                        sk.translated, sk.names, sk.joint_map, motion.fps)  # fmt: skip


@pytest.mark.parametrize("action", ["raise-up-right-hand", "raise-up-left-hand",
                                    "raise-up-both-hands"])  # fmt: skip
def test_a_reach_keyframe_is_the_middle_of_the_highest_plateau(action):
    for path in clips_of(action, 6):
        motion = read_bvh(str(path))
        start, end, keyframes, hands, kind = kernel_action(motion)["action"]
        assert kind == "reach" and hands == hands_by_name(path), (path.name, hands, kind)
        assert (start, end) == (0, len(motion.rotations) - 1)  # Bandai's move from the first frame
        assert abs(keyframes[1] - own_plateau_middle(motion, hands)) <= 1, (path.name, keyframes)


@pytest.mark.parametrize("action", ["wave-right-hand", "wave-left-hand", "wave-both-hands"])
def test_a_wave_runs_from_its_first_turn_to_its_last(action):
    for path in clips_of(action, 3):
        motion = read_bvh(str(path))
        start, end, keyframes, hands, kind = kernel_action(motion)["action"]
        assert kind == "repeat" and hands == hands_by_name(path), (path.name, hands, kind)
        first, last = own_wave_span(motion, hands)
        # within a third of a second: a wave's swing takes about half a second
        assert abs(keyframes[1] - first) <= 10 and abs(keyframes[2] - last) <= 10, (
            path.name, keyframes, (first, last))  # fmt: skip
        assert keyframes[2] - keyframes[1] > 0.6 * (last - first)


def held(motion, before: int, after: int, name: str):
    """The motion with its first frame held `before` frames and its last `after`."""
    def padded(a):
        return None if a is None else np.concatenate(
            [np.repeat(a[:1], before, 0), a, np.repeat(a[-1:], after, 0)])  # fmt: skip

    return dataclasses.replace(motion, rotations=padded(motion.rotations),
                               translations=padded(motion.translations), name=name)  # fmt: skip


@pytest.fixture(scope="module")
def dsn(cluster, tmp_path_factory):
    folder = tmp_path_factory.mktemp("actions")
    raise_right = read_bvh(str(clips_of("raise-up-right-hand", 1)[0]))
    write_bvh_file(held(raise_right, HOLD, HOLD, "held_raise"), folder / "held_raise.bvh")
    still = dataclasses.replace(raise_right, rotations=np.repeat(raise_right.rotations[:1], 60, 0),
                                translations=np.repeat(raise_right.translations[:1], 60, 0))
    write_bvh_file(still, folder / "still.bvh")
    with scratch_database(cluster, f"actions_{os.getpid()}") as dsn:
        files = [*clips_of("raise-up-right-hand", 2), *clips_of("wave-left-hand", 1)]
        for collection, paths in (("raises", files[:2]), ("waves", files[2:]),
                                  ("made", [folder / "held_raise.bvh", folder / "still.bvh"])):
            r = modb(dsn, "load", *map(str, paths), "--collection", collection, "--no-snippets",
                     "-q")  # fmt: skip
            assert r.returncode == 0, r.stderr
        yield dsn


def segments(conn, clip) -> list[dict]:
    return conn.execute(
        "SELECT v.meta->'annotations' FROM modb.current_clips c "
        "JOIN modb.clip_versions v USING (clip_id, version) WHERE c.clip_id = %s", [clip],
    ).fetchone()[0] or []  # fmt: skip


def clip_named(conn, name) -> int:
    return conn.execute("SELECT clip_id FROM modb.current_clips WHERE name = %s",
                        [name]).fetchone()[0]  # fmt: skip


def etag(conn, clip) -> str:
    return conn.execute(
        "SELECT md5(v.meta::text) FROM modb.current_clips c "
        "JOIN modb.clip_versions v USING (clip_id, version) WHERE c.clip_id = %s", [clip],
    ).fetchone()[0]  # fmt: skip


def test_held_frames_give_a_lead_in_and_a_lead_out_and_a_run_again_changes_nothing(dsn):
    r = modb(dsn, "annotate", "--action", "raise_right_hand", "made/held_raise")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        clip = clip_named(conn, "held_raise")
        stored = segments(conn, clip)
        n = len(read_motion(conn, clip).rotations)
        source = read_bvh(str(clips_of("raise-up-right-hand", 1)[0]))
        before = etag(conn, clip)
    idle = [s for s in stored if s["name"] == "idle"]
    (action,) = [s for s in stored if s["name"] == "raise_right_hand"]
    assert [(s["start"], s["auto"], s["action"]) for s in idle] == [
        (0, True, "raise_right_hand"), (action["end"], True, "raise_right_hand")]  # fmt: skip
    # the still stretch ends where the motion starts moving: within a tenth of a second of it
    assert HOLD - 4 <= idle[0]["end"] == action["start"] <= HOLD
    assert n - 1 - HOLD <= action["end"] <= n - 1 - HOLD + 4 and idle[1]["end"] == n - 1
    assert action["keyframes"][1] == HOLD + own_plateau_middle(source, ["right"])
    assert action["hands"] == ["right"] and action["kind"] == "reach" and action["auto"] is True
    r = modb(dsn, "annotate", "--action", "raise_right_hand", "made/held_raise")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        assert etag(conn, clip) == before
    # finding the steps after it keeps the action and its lead-in and lead-out
    r = modb(dsn, "annotate", "--steps", "made/held_raise")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        assert all(s in segments(conn, clip) for s in stored)


def test_a_persons_segments_and_other_actions_are_kept(dsn):
    with connect(dsn) as conn:
        clip = conn.execute(
            "SELECT min(clip_id) FROM modb.current_clips WHERE collection = 'raises'").fetchone()[0]
    assert modb(dsn, "annotate", "--action", "raise_right_hand", f"id:{clip}").returncode == 0
    with connect(dsn) as conn:
        (found,) = segments(conn, clip)
    mine = {"name": "raise_right_hand", "start": 3, "end": 30}  # a person's: no "auto"
    other = {"name": "reach", "start": 0, "end": 20, "auto": True}  # another action's
    with connect(dsn) as conn:
        conn.execute(
            "UPDATE modb.clip_versions v SET meta = jsonb_set(v.meta, '{annotations}', %s) "
            "FROM modb.current_clips c WHERE c.clip_id = v.clip_id AND c.version = v.version "
            "AND c.clip_id = %s",
            [psycopg.types.json.Jsonb([mine, other, dict(found, end=found["end"] - 1,
                                                          keyframes=[found["start"]])]), clip],
        )
    r = modb(dsn, "annotate", "--action", "raise_right_hand", f"id:{clip}")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        after = segments(conn, clip)
    assert mine in after and other in after and found in after and len(after) == 3


def test_a_still_clip_is_refused_saying_so_and_nothing_is_written(dsn):
    with connect(dsn) as conn:
        clip = clip_named(conn, "still")
        before = etag(conn, clip)
    r = modb(dsn, "annotate", "--action", "raise_right_hand", "made/still")
    assert r.returncode != 0
    assert f"clip {clip}" in r.stderr and "no hand moves" in r.stderr, r.stderr
    assert "--segment raise_right_hand:START-END" in r.stderr, r.stderr
    with connect(dsn) as conn:
        assert etag(conn, clip) == before and segments(conn, clip) == []
        with pytest.raises(psycopg.Error, match="no hand moves"):
            conn.execute("SELECT * FROM modb.annotate_action(%s, 'wave')", [clip])


def test_cmu_walks_are_refused_never_crash():
    from modb.loader.asf import read_amc, read_asf

    from modb_kernel import actions

    asf = read_asf(str(mocap("cmu", "16", "16.asf")))
    for path in sorted(mocap("cmu", "16").glob("16_*.amc"))[:4]:
        motion = read_amc(str(path), asf)
        with pytest.raises(actions.ActionError, match="travels|no hand moves"):
            kernel_action(motion)


def test_rest_with_a_token_and_the_job_for_a_collection(dsn):
    import httpx
    from support.browser import serving
    from support.jobs import stop, until, worker

    from modb.database.cluster import ensure_writer_role

    with psycopg.connect(dsn, autocommit=True) as conn:
        ensure_writer_role(conn)
        clip = conn.execute(
            "SELECT max(clip_id) FROM modb.current_clips WHERE collection = 'raises'").fetchone()[0]
        wave = conn.execute("SELECT clip_id FROM modb.current_clips WHERE collection = 'waves'"
                            ).fetchone()[0]  # fmt: skip
    tokens = {}
    for name, role in (("action-loader", "loader"), ("action-reader", "reader")):
        r = modb(dsn, "token", "create", name, "--role", role)
        assert r.returncode == 0, r.stderr
        tokens[role] = {"Authorization": f"Bearer {r.stdout.strip()}"}
    body = {"action": "raise_right_hand"}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        assert client.post(f"/api/clips/{clip}/action", json=body).status_code == 401
        assert client.post(f"/api/clips/{clip}/action", json=body,
                           headers=tokens["reader"]).status_code == 403  # fmt: skip
        r = client.post(f"/api/clips/{clip}/action", json=body, headers=tokens["loader"])
        assert r.status_code == 200, r.text
        (made,) = r.json()["segments"]
        assert made["name"] == "raise_right_hand" and made["hands"] == ["right"]
        r = modb(dsn, "worker", "--init")
        assert r.returncode == 0, r.stderr
        queued = client.post("/api/collections/waves/action", json={"action": "wave_left_hand"},
                             headers=tokens["loader"])  # fmt: skip
        assert queued.status_code == 202 and queued.json()["kind"] == "modb.annotate_action", (
            queued.text)  # fmt: skip
        w = worker(dsn)
        try:
            with connect(dsn) as conn:
                state = until(conn, queued.json()["id"], lambda j: j["state"] == "done", 60, "done")
        finally:
            stop(w)
    (result,) = state["result"]["clips"]
    with connect(dsn) as conn:
        stored = segments(conn, wave)
    assert result["clip_id"] == wave and result["segments"] == stored
    assert stored[0]["name"] == "wave_left_hand" and stored[0]["kind"] == "repeat"
