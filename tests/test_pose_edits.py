"""Edit scripts' pose edits (issue 64): `ik` moves a joint (by its standard name) by an offset in
the character's heading frame at an instant and `rotate` turns it in its parent frame, each change
spread by a cubic B-spline falloff. On real rigs (Bandai's BVH, CMU's ASF/AMC), judged by the tests'
own forward kinematics and heading (scipy): a reachable target met within 1 mm, an unreachable one
at the nearest point the chain reaches with its distance said; frames outside the blend range
byte-equal; inside it no pose jump above the source's p99.9 and the joint's path as smooth as the
source's; bone lengths kept; the same script on both skeletons; refusals that name the command;
and the script saved and applied by `modb edit apply`, REST and SQL, replayed byte for byte."""

from __future__ import annotations

import json
import os

import httpx
import numpy as np
import psycopg
import pytest
from scipy.spatial.transform import Rotation
from support import own_kinematics
from support.browser import serving
from support.commands import run_modb, run_modb_here
from support.data import mocap
from support.databases import scratch_database

from modb.clips import read_motion
from modb.database import pgarray
from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import edit_clips, edits, retarget

WALK = ("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
CMU = ("cmu", "16")
BLEND = 0.5  # seconds before and after
# The same commands on every rig: by standard joint names, offsets in the heading frame.
REACHABLE = [
    ("right_wrist", 2.0, [0.0, 0.1, 0.05]),  # the hand 10 cm up and 5 cm forward
    ("left_wrist", 2.5, [0.06, -0.04, 0.08]),
    ("left_ankle", 3.0, [0.03, 0.05, 0.0]),  # the foot lifted 5 cm, 3 cm to the character's left
]
SCRIPT = [
    {"op": "ik", "joint": "right_wrist", "time": 2.0, "offset": [0.0, 0.1, 0.05],
     "before": BLEND, "after": BLEND},
    {"op": "rotate", "joint": "left_elbow", "time": 3.0, "rotation": [0.0, 0.0, -20.0],
     "before": BLEND, "after": BLEND},
]  # fmt: skip


def _rigs():
    walk, asf = mocap(*WALK), mocap(*CMU, "16.asf")
    return {"bandai": read_bvh(str(walk)),
            "cmu": read_amc(str(mocap(*CMU, "16_15.amc")), read_asf(str(asf)))}  # fmt: skip


@pytest.fixture(scope="module", params=["bandai", "cmu"])
def motion(request):
    return _rigs()[request.param]


def clip_of(motion) -> dict:
    """The kernel's clip (as the server reads one) of a loaded motion."""
    sk = motion.skeleton
    return {
        "skeleton": retarget.skeleton(sk.hierarchy_json(), sk.joint_map),
        "fps": motion.fps,
        "rotations": np.asarray(motion.rotations, dtype=np.float64),
        "translations": np.asarray(motion.translations, dtype=np.float64),
    }


def positions(sk, rotations, translations) -> np.ndarray:
    return own_kinematics.world_positions(sk.parents, sk.offsets, sk.translated, rotations,
                                          translations)  # fmt: skip


def world_rotation(sk, rotations, joint) -> Rotation:
    return own_kinematics.world_rotation(sk.parents, rotations, joint)


def heading(sk, p, fps, frame) -> float:
    """The character's heading at a frame (DESIGN.md, docs/querying.md): forward = hip axis x up
    (its +X, left, times +Y is +Z), averaged over +-0.25 s."""
    left, right = (sk.index(sk.joint_map[s]) for s in ("left_hip", "right_hip"))
    half = round(0.25 * fps)
    window = slice(max(0, frame - half), frame + half + 1)
    axis = p[window, left] - p[window, right]
    forward = np.cross(axis, [0.0, 1.0, 0.0])
    forward /= np.linalg.norm(forward, axis=1, keepdims=True)
    mean = forward.sum(0)
    return float(np.arctan2(mean[0], mean[2]))


def own_target(motion, joint, time, offset):
    """(frame, target): where the test itself says the joint should go."""
    sk = motion.skeleton
    frame = int(round(time * motion.fps))
    p = positions(sk, motion.rotations, motion.translations)
    turn = Rotation.from_rotvec([0.0, heading(sk, p, motion.fps, frame), 0.0])
    return frame, p[frame, sk.index(sk.joint_map[joint])] + turn.apply(offset)


def outside(n, frame, fps):
    """Frames the blend range leaves alone: BLEND seconds or more from the frame."""
    t = np.arange(n) - frame
    return np.abs(t) >= BLEND * fps


def cardinal(x):
    """The uniform cubic B-spline, 1 at 0."""
    x = np.abs(x)
    return np.where(x < 2, ((2 - x) ** 3 - 4 * np.maximum(0.0, 1 - x) ** 3) / 4, 0.0)


def displacements(sk, p) -> np.ndarray:
    """Per frame and joint, how far the joint moves from the frame before, relative to the
    pelvis's ground point."""
    ground = p[:, sk.index(sk.joint_map["pelvis"])] * [1.0, 0.0, 1.0]
    relative = p - ground[:, None]
    return np.linalg.norm(np.diff(relative, axis=0), axis=-1)


def bone_lengths(sk, p) -> np.ndarray:
    kids = [j for j, parent in enumerate(sk.parents) if parent >= 0]
    return np.linalg.norm(p[:, kids] - p[:, [sk.parents[j] for j in kids]], axis=-1)


def test_ik_meets_the_target_and_keeps_the_rest(motion):
    sk, clip = motion.skeleton, clip_of(motion)
    before = positions(sk, motion.rotations, motion.translations)
    jump = np.percentile(displacements(sk, before), 99.9)
    for joint, time, offset in REACHABLE:
        command = {"op": "ik", "joint": joint, "time": time, "offset": offset, "before": BLEND,
                   "after": BLEND}  # fmt: skip
        out, notes = edits.apply_with_notes(clip, [command])
        frame, target = own_target(motion, joint, time, offset)
        j = sk.index(sk.joint_map[joint])
        after = positions(sk, out["rotations"], out["translations"])
        assert np.linalg.norm(after[frame, j] - target) < 1e-3, joint
        note = notes[0]
        assert note["met"] and note["distance_m"] < 1e-3 and note["frame"] == frame
        assert np.allclose(note["target"], target, atol=1e-6)
        assert np.allclose(note["reached"], after[frame, j], atol=1e-9)
        # outside the blend range nothing changes, nor do joints off the chain, nor translations
        still = outside(motion.n_frames, frame, motion.fps)
        assert np.array_equal(out["rotations"][still], clip["rotations"][still])
        assert out["translations"] is clip["translations"]
        moved = [sk.index(n) for n in note["chain"]] + [j]
        others = [k for k in range(len(sk.names)) if k not in moved]
        assert np.array_equal(out["rotations"][:, others], clip["rotations"][:, others])
        changed = np.flatnonzero(np.any(out["rotations"] != clip["rotations"], axis=(1, 2)))
        assert changed.min() > frame - BLEND * motion.fps
        assert changed.max() < frame + BLEND * motion.fps
        assert np.abs(bone_lengths(sk, after) - bone_lengths(sk, before)).max() < 1e-9
        # inside: no jump past the source's p99.9 (where the source itself jumps further, past
        # its own), the joint's path as smooth as the source's
        inside = slice(changed.min() - 1, changed.max() + 2)  # with the frames either side
        own = displacements(sk, before[inside])
        assert np.all(displacements(sk, after[inside]) <= np.maximum(own, jump)), joint
        bend = np.linalg.norm(np.diff(after[inside, j], 2, axis=0), axis=-1)
        assert bend.max() <= np.linalg.norm(np.diff(before[:, j], 2, axis=0), axis=-1).max()
        # the joint keeps its world orientation (no orientation given)
        kept = world_rotation(sk, out["rotations"], j) * world_rotation(sk, clip["rotations"],
                                                                        j).inv()  # fmt: skip
        assert kept.magnitude()[frame] < 1e-6


def test_ik_turns_the_joint_in_the_heading_frame_and_takes_a_chain(motion):
    sk, clip = motion.skeleton, clip_of(motion)
    joint, time, offset = REACHABLE[0]
    command = {"op": "ik", "joint": joint, "time": time, "offset": offset,
               "orientation": [10.0, 30.0, -5.0], "before": BLEND, "after": BLEND}  # fmt: skip
    out, notes = edits.apply_with_notes(clip, [command])
    frame, target = own_target(motion, joint, time, offset)
    j = sk.index(sk.joint_map[joint])
    assert np.linalg.norm(positions(sk, out["rotations"], clip["translations"])[frame, j]
                          - target) < 1e-3  # fmt: skip
    p = positions(sk, motion.rotations, motion.translations)
    turn = Rotation.from_rotvec([0.0, heading(sk, p, motion.fps, frame), 0.0])
    change = Rotation.from_rotvec(turn.apply(np.radians(command["orientation"])))
    want = change * world_rotation(sk, clip["rotations"][frame:frame + 1], j)
    got = world_rotation(sk, out["rotations"][frame:frame + 1], j)
    assert (got * want.inv()).magnitude()[0] < 1e-6
    # chain 1: only the joint's parent (and the joint's own rotation) turn
    out, notes = edits.apply_with_notes(clip, [dict(command, chain=1)])
    changed = np.flatnonzero(np.any(out["rotations"] != clip["rotations"], axis=(0, 2)))
    assert list(changed) == sorted([sk.parents[j], j]) and len(notes[0]["chain"]) == 1


def test_an_unreachable_target_ends_at_the_nearest_point_and_says_how_far(motion):
    sk, clip = motion.skeleton, clip_of(motion)
    joint, time, offset = "right_wrist", 2.0, [0.0, 0.0, 1.5]  # 1.5 m ahead: out of the arm's reach
    command = {"op": "ik", "joint": joint, "time": time, "offset": offset, "before": BLEND,
               "after": BLEND}  # fmt: skip
    out, notes = edits.apply_with_notes(clip, [command])
    frame, target = own_target(motion, joint, time, offset)
    note = notes[0]
    chain = [sk.index(n) for n in note["chain"]] + [sk.index(sk.joint_map[joint])]
    before = positions(sk, motion.rotations, motion.translations)[frame]
    after = positions(sk, out["rotations"], clip["translations"])[frame]
    # the nearest point the chain reaches: from its first joint (which stays), straight toward the
    # target, as far as its bones reach
    root, length = before[chain[0]], bone_lengths_along(before, chain)
    nearest = root + (target - root) / np.linalg.norm(target - root) * length
    assert np.linalg.norm(after[chain[-1]] - nearest) < 1e-3
    assert abs(note["distance_m"] - np.linalg.norm(target - nearest)) < 1e-3
    assert not note["met"] and np.allclose(note["reached"], after[chain[-1]], atol=1e-9)
    assert note["message"].startswith("command 1: ik: right_wrist at frame")
    assert f"{note['distance_m'] * 1000:.1f} mm from the target" in note["message"]


def bone_lengths_along(p, chain) -> float:
    return float(sum(np.linalg.norm(p[b] - p[a]) for a, b in zip(chain, chain[1:])))


def test_rotate_premultiplies_the_local_rotation_and_spreads_it(motion):
    sk, clip = motion.skeleton, clip_of(motion)
    command = {"op": "rotate", "joint": "left_elbow", "time": 3.0, "rotation": [10.0, -20.0, 30.0],
               "before": BLEND, "after": BLEND}  # fmt: skip
    out, notes = edits.apply_with_notes(clip, [command])
    j, frame = sk.index(sk.joint_map["left_elbow"]), int(round(3.0 * motion.fps))
    rot = own_kinematics.rotations_of
    turn = Rotation.from_rotvec(np.radians(command["rotation"]))
    assert ((rot(out["rotations"][frame, j]) * (turn * rot(clip["rotations"][frame, j])).inv())
            .magnitude()[0] < 1e-9)  # fmt: skip
    # each frame turned by a share of it: the cubic B-spline of the blend
    share = cardinal(2 * (np.arange(motion.n_frames) - frame) / (BLEND * motion.fps))
    got = rot(out["rotations"][:, j]) * rot(clip["rotations"][:, j]).inv()
    assert np.allclose(got.magnitude(), share * turn.magnitude(), atol=1e-9)
    still = outside(motion.n_frames, frame, motion.fps)
    assert np.array_equal(out["rotations"][still], clip["rotations"][still])
    others = [k for k in range(len(sk.names)) if k != j]
    assert np.array_equal(out["rotations"][:, others], clip["rotations"][:, others])
    assert notes[0]["frame"] == frame and notes[0]["skeleton_joint"] == sk.joint_map["left_elbow"]


def test_refusals_name_the_command_and_what_to_give():
    ik = {"op": "ik", "joint": "right_wrist", "time": 1.0, "offset": [0, 0.1, 0], "before": 0.5,
          "after": 0.5}  # fmt: skip
    assert edits.script_errors([ik, {**SCRIPT[1]}]) == []
    for change, said in (
        ({"joint": ""}, 'command 2: ik: "joint" must be a standard joint name'),
        ({"joint": 3}, 'command 2: ik: "joint" must be a standard joint name'),
        ({"time": -1}, 'command 2: ik: "time" must be a number from 0'),
        ({"offset": [0, 1]}, 'command 2: ik: "offset" must be 3 numbers [x, y, z] from -2 to 2 m'),
        ({"offset": [0, 3, 0]}, '"offset" must be 3 numbers'),
        ({"offset": [0, float("nan"), 0]}, '"offset" must be 3 numbers'),
        ({"orientation": [0, 0, 400]}, '"orientation" must be 3 numbers [x, y, z] from -360'),
        ({"chain": 0}, 'command 2: ik: "chain" must be how many joints above the joint may turn'),
        ({"chain": 2.5}, '"chain" must be how many joints'),
        ({"before": 11}, 'command 2: ik: "before" must be a number from 0 to 10'),
        ({"after": None}, '"after" must be a number from 0 to 10'),
    ):
        problems = edits.script_errors([{"op": "mirror"}, {**ik, **change}])
        assert any(said in p for p in problems), (change, problems)
    missing = {k: v for k, v in SCRIPT[1].items() if k != "rotation"}
    assert edits.script_errors([missing]) == ['command 1: rotate: "rotation" is missing']
    # what only the clip tells: its joint map and its length
    clip = clip_of(_rigs()["bandai"])
    for change, said in (
        ({"joint": "right_hand"}, 'command 1: ik: "joint" must be a standard joint name of the '
                                  "skeleton's joint map (pelvis, "),
        ({"time": 60.0}, 'command 1: ik: "time" must be within the clip: seconds from 0 to 6.867'),
        ({"joint": "pelvis"}, "command 1: ik: no joint above pelvis may turn"),
        # and a script never saved (a preview's) has its parameters checked when it is applied
        ({"before": 11}, 'command 1: ik: "before" must be a number from 0 to 10'),
        ({"offset": [0, float("nan"), 0]}, 'command 1: ik: "offset" must be 3 numbers'),
    ):  # fmt: skip
        with pytest.raises(edits.EditError) as e:
            edits.apply(clip, [{**ik, **change}])
        assert said in str(e.value)


# The saved script applied by every path (a database with the real loader's clips)


@pytest.fixture(scope="module")
def stored(cluster):
    """A database holding Bandai's walk and CMU 16_15 (two skeletons, one joint map of standard
    names), job tables, a loader token, `modb serve`: (dsn, token, client, clip ids)."""
    walk, amc = mocap(*WALK), mocap(*CMU, "16_15.amc")
    with scratch_database(cluster, f"pose_edits_{os.getpid()}") as dsn:
        for path, collection in ((walk, "bandai"), (amc, "cmu16")):
            r = run_modb(dsn, "load", path, "-q", "--collection", collection)
            assert r.returncode == 0, r.stderr
        r = run_modb_here(dsn, "worker", "--init")  # job tables: `modb edit apply` runs a job
        assert r.returncode == 0, r.stderr
        r = run_modb(dsn, "token", "create", "editor", "--role", "loader")
        assert r.returncode == 0, r.stderr
        with psycopg.connect(dsn) as conn:
            clips = dict(conn.execute("SELECT collection, clip_id FROM modb.current_clips"))
        with serving(dsn) as address:
            with httpx.Client(base_url=f"http://{address}", timeout=120) as client:
                yield dsn, r.stdout.strip(), client, clips


def version(dsn, clip, number=None):
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        return read_motion(conn, clip, number)


def check_script(before, after, also=()):
    """The stored version `after` made from `before` by SCRIPT (and commands at the times `also`),
    judged by the tests' own FK."""
    sk = after.skeleton
    joint, time, offset = REACHABLE[0]
    frame, target = own_target(before, joint, time, offset)
    p = positions(sk, after.rotations, after.translations)
    assert np.linalg.norm(p[frame, sk.index(sk.joint_map[joint])] - target) < 1e-3
    elbow, turned = sk.index(sk.joint_map["left_elbow"]), int(round(3.0 * before.fps))
    rot = own_kinematics.rotations_of
    turn = Rotation.from_rotvec(np.radians(SCRIPT[1]["rotation"]))
    want = turn * rot(before.rotations[turned, elbow])
    assert (rot(after.rotations[turned, elbow]) * want.inv()).magnitude()[0] < 2e-4  # float4
    still = np.ones(before.n_frames, bool)
    for at in (frame, turned, *(int(round(t * before.fps)) for t in also)):
        still &= outside(before.n_frames, at, before.fps)
    assert np.array_equal(after.rotations[still], before.rotations[still])
    assert np.array_equal(after.translations, before.translations)


def test_cli_applies_and_replays_the_script_byte_for_byte(stored):
    dsn, _, _, clips = stored
    clip = clips["bandai"]
    original = version(dsn, clip)
    with psycopg.connect(dsn) as conn:  # a preview: the kernel on the clip as the database holds it
        preview, notes = edits.apply_with_notes(
            edit_clips.current_clip(WorkerDatabase(conn), clip), SCRIPT)
    r = run_modb_here(dsn, "edit", "save", "pose", "--commands", json.dumps(SCRIPT))
    assert r.returncode == 0, r.stderr
    r = run_modb_here(dsn, "edit", "apply", "pose", "bandai")
    assert r.returncode == 0, r.stderr
    made = version(dsn, clip)
    check_script(original, made)
    assert np.abs(made.rotations - preview["rotations"].astype(np.float32)).max() < 1e-6
    with psycopg.connect(dsn) as conn:
        record = conn.execute(
            "SELECT load_params->'edit_script' FROM modb.clip_versions WHERE clip_id = %s AND "
            "version = %s", [clip, made.meta["version"]]).fetchone()[0]  # fmt: skip
    assert record["commands"] == SCRIPT and record["from_version"] == original.meta["version"]
    assert [n["op"] for n in record["notes"]] == ["ik", "rotate"] and record["notes"][0]["met"]
    with psycopg.connect(dsn) as conn:  # a job (no worker: run by the command), its result
        (result,) = conn.execute("SELECT result FROM modb_jobs.progress ORDER BY job_id DESC "
                                 "LIMIT 1").fetchone()  # fmt: skip
    assert result["clips"][0]["notes"] == record["notes"]
    for stored_note, previewed in zip(record["notes"], notes):
        assert stored_note["frames"] == previewed["frames"]
        assert np.allclose(stored_note.get("reached", 0), previewed.get("reached", 0), atol=1e-6)
    # replayed on the original version (made current again): the same frames, byte for byte
    r = run_modb_here(dsn, "clip", "restore", str(clip), "--version", str(original.meta["version"]))
    assert r.returncode == 0, r.stderr
    r = run_modb_here(dsn, "edit", "apply", "pose", str(clip))
    assert r.returncode == 0, r.stderr
    again = version(dsn, clip)
    assert again.meta["version"] > made.meta["version"] + 1
    assert np.array_equal(again.rotations, made.rotations)
    assert np.array_equal(again.translations, made.translations)
    # a target out of reach: met as nearly as the arm can, and said
    far = [{**SCRIPT[0], "offset": [0.0, 0.0, 1.9]}]
    assert run_modb_here(dsn, "edit", "save", "far", "--commands", json.dumps(far)).returncode == 0
    r = run_modb_here(dsn, "edit", "apply", "far", str(clip))
    assert r.returncode == 0, r.stderr
    said = "command 1: ik: right_wrist at frame 60: the target is out of the chain's reach"
    assert said in r.stdout and "mm from the target" in r.stdout, r.stdout


def test_rest_and_sql_apply_it_on_another_skeleton_by_standard_names(stored):
    dsn, token, client, clips = stored
    clip = clips["cmu16"]
    original = version(dsn, clip)
    h = {"Authorization": f"Bearer {token}"}
    far = {"op": "ik", "joint": "left_wrist", "time": 1.0, "offset": [0.0, 0.0, 1.9],
           "before": BLEND, "after": BLEND}  # fmt: skip
    r = client.put("/api/edit-scripts/pose-rest", json={"commands": SCRIPT + [far]}, headers=h)
    assert r.status_code in (200, 201), r.text
    r = client.post("/api/edit-scripts/pose-rest/apply", json={"clips": [clip]}, headers=h)
    assert r.status_code == 200, r.text
    (result,) = r.json()["results"]
    made = version(dsn, clip)
    assert result["version"] == made.meta["version"]
    assert made.skeleton.names != version(dsn, clips["bandai"]).skeleton.names
    check_script(original, made, also=[far["time"]])
    notes = result["notes"]
    assert [n["command"] for n in notes] == [1, 2, 3] and notes[0]["met"] and not notes[2]["met"]
    assert notes[2]["distance_m"] > 0.5 and "out of the chain's reach" in notes[2]["message"]
    # SQL, on the version REST made: the same kernel code in the server
    with psycopg.connect(dsn) as conn:
        rows = conn.execute("SELECT * FROM modb.apply_edit_script('pose', %s)",
                            [[clip]]).fetchall()  # fmt: skip
    assert rows[0][1] == made.meta["version"] + 1
    check_script(made, version(dsn, clip))


def test_a_pose_edit_that_does_not_fit_the_clip_stores_nothing(stored):
    dsn, token, client, clips = stored
    h = {"Authorization": f"Bearer {token}"}
    bad = {**SCRIPT[0], "joint": "tail"}
    r = client.put("/api/edit-scripts/bad", json={"commands": [SCRIPT[1], bad]}, headers=h)
    assert r.status_code in (200, 201), r.text
    with psycopg.connect(dsn) as conn:
        versions = conn.execute("SELECT count(*) FROM modb.clip_versions").fetchone()[0]
    r = client.post("/api/edit-scripts/bad/apply", json={"clips": [clips["cmu16"]]}, headers=h)
    said = 'command 2: ik: "joint" must be a standard joint name'
    assert r.status_code == 400 and said in r.json()["error"], r.text
    r = run_modb_here(dsn, "edit", "apply", "bad", "bandai")
    assert r.returncode != 0 and "command 2: ik:" in r.stderr, r.stderr
    r = client.put("/api/edit-scripts/worse", json={"commands": [{**bad, "offset": [0, 5, 0]}]},
                   headers=h)  # fmt: skip
    assert r.status_code == 400 and '"offset" must be 3 numbers' in r.json()["error"], r.text
    with psycopg.connect(dsn) as conn:
        assert conn.execute("SELECT count(*) FROM modb.clip_versions").fetchone()[0] == versions
