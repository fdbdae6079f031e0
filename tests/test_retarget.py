"""Retargeting (issue 26) on real capture, checked with this test's own forward kinematics (scipy),
not the kernel's: CMU 131 (ASF/AMC, 120 fps) onto a Bandai skeleton (BVH, 30 fps) and back; every
mapped limb bone and the trunk points where the source's does, a round trip comes back, no foot
goes below the floor, a Bandai rig whose rest pose is re-posed gets the same directions, and the
new clips are linked to their sources, which stay as they were."""

from __future__ import annotations

import os

import numpy as np
import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database
from support.snippet_oracle import motion_world

from modb.clips import read_motion
from modb.database import pgarray

BONES = {
    "left thigh": ("left_hip", "left_knee"),
    "right thigh": ("right_hip", "right_knee"),
    "left shin": ("left_knee", "left_ankle"),
    "right shin": ("right_knee", "right_ankle"),
    "left upper arm": ("left_shoulder", "left_elbow"),
    "right upper arm": ("right_shoulder", "right_elbow"),
    "left forearm": ("left_elbow", "left_wrist"),
    "right forearm": ("right_elbow", "right_wrist"),
    "trunk": ("pelvis", "neck"),
}
FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")


@pytest.fixture(scope="module")
def pair(cluster):
    """Two CMU 131 trials and two Bandai walks, each retargeted onto the other's skeleton."""
    with scratch_database(cluster, f"retarget_{os.getpid()}") as dsn:
        trials = [mocap("cmu", "131", f"131_0{i}.amc") for i in (3, 4)]
        walks = sorted(mocap("bandai-2-dev", "data").glob("dataset-2_walk_active_*.bvh"))[:2]
        for files, collection in ((trials, "cmu"), (walks, "bandai")):
            r = run_modb(dsn, "load", *files, "--collection", collection, "-q")
            assert r.returncode == 0, r.stderr
        for source, target, into in (
            ("cmu", f"bandai/{walks[0].stem}", "cmu on bandai"),
            ("bandai", "cmu/131_03", "bandai on cmu"),
        ):
            r = run_modb(dsn, "retarget", source, "--to", target, "--collection", into, "-q")
            assert r.returncode == 0, r.stderr
        yield dsn


def motions(dsn: str, collection: str) -> dict[str, object]:
    with psycopg.connect(dsn) as conn:
        pgarray.register(conn)
        ids = conn.execute(
            "SELECT clip_id, name FROM modb.current_clips WHERE collection = %s ORDER BY 2",
            [collection],
        ).fetchall()
        return {name: read_motion(conn, clip_id) for clip_id, name in ids}


def positions(motion) -> np.ndarray:
    """World positions (frames, joints, 3) by the tests' own forward kinematics (scipy)."""
    return motion_world(motion)[0]


def directions(motion, frames=slice(None)) -> np.ndarray:
    """Unit world directions (frames, bones, 3) of BONES."""
    p = positions(motion)[frames]
    sk = motion.skeleton
    at = {s: sk.index(j) for s, j in sk.joint_map.items()}
    v = np.stack([p[:, at[b]] - p[:, at[a]] for a, b in BONES.values()], axis=1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def degrees(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def paired(source, target):
    """The frames of source and target at the same instants (CMU's 120 fps is 4x Bandai's 30)."""
    ratio = source.fps / target.fps
    if ratio >= 1:
        k = round(ratio)
        n = min(target.n_frames, (source.n_frames - 1) // k + 1)
        return slice(0, n * k, k), slice(0, n)
    k = round(1 / ratio)
    n = min(source.n_frames, (target.n_frames - 1) // k + 1)
    return slice(0, n), slice(0, n * k, k)


@pytest.mark.parametrize("source, target", [("cmu", "cmu on bandai"), ("bandai", "bandai on cmu")])
def test_bones_point_where_the_sources_do(pair, source, target):
    sources, targets = motions(pair, source), motions(pair, target)
    assert sources.keys() == targets.keys() and len(sources) == 2
    for name, original in sources.items():
        moved = targets[name]
        assert moved.skeleton.names != original.skeleton.names  # really on the other skeleton
        s, t = paired(original, moved)
        error = degrees(directions(original, s), directions(moved, t))
        p99 = dict(zip(BONES, np.percentile(error, 99, axis=0).round(2), strict=True))
        assert max(p99.values()) < 5, p99  # the issue allows 15; 0.16.0 keeps the trunk within ~1
        # no foot below the floor by more than 2 cm
        sk = moved.skeleton
        feet = [sk.index(sk.joint_map[f]) for f in FEET]
        assert positions(moved)[:, feet, 1].min() > -0.02


def test_a_round_trip_comes_back(pair):
    r = run_modb(pair, "retarget", "cmu on bandai", "--to", "cmu/131_03", "--collection", "back")
    assert r.returncode == 0, r.stderr
    originals, returned = motions(pair, "cmu"), motions(pair, "back")
    for name, original in originals.items():
        back = returned[name]
        assert back.fps == original.fps == 120  # the destination's rate by default
        frames = slice(0, min(original.n_frames, back.n_frames), 4)  # the 30 fps instants
        error = degrees(directions(original, frames), directions(back, frames))
        assert np.percentile(error, 99) < 5, np.percentile(error, 99, axis=0)


def test_a_reposed_rest_pose_gives_the_same_directions(pair):
    """The Bandai rig with its rest pose re-posed to a standing frame (offsets turned with it):
    another rest, the same bones; the retargeted directions must not change."""
    from dataclasses import replace

    from modb.editing.retarget import retarget_motion
    from modb.motion import Joint

    cmu = motions(pair, "cmu")["131_03"]
    bandai = motions(pair, "bandai")
    walk = bandai[sorted(bandai)[0]]
    sk = walk.skeleton
    standing = positions(walk)[0]
    # each joint's offset becomes its bone as it stands in frame 0, in world axes
    reposed_joints = [
        replace(j, offset=tuple(standing[i] - standing[j.parent]) if j.parent >= 0 else j.offset)
        for i, j in enumerate(sk.joints)
    ]
    reposed = replace(sk, joints=[Joint(**vars(j)) for j in reposed_joints], joint_axes={})
    assert np.abs(reposed.offsets - sk.offsets).max() > 0.1  # a different rest pose
    onto_original = retarget_motion(cmu, sk, 30.0, walk)
    onto_reposed = retarget_motion(cmu, reposed, 30.0)  # its rest stands: no reference needed
    error = degrees(directions(onto_original), directions(onto_reposed))
    assert np.percentile(error, 99) < 1.0, np.percentile(error, 99, axis=0)


def test_new_clips_link_their_sources_which_stay_as_they_were(pair):
    with psycopg.connect(pair) as conn:
        rows = conn.execute(
            "SELECT c.meta, v.meta->'retargeted_from', cv.load_params->'retargeted_from', "
            "(SELECT count(*) FROM modb.clip_versions s WHERE s.clip_id = "
            "(v.meta->'retargeted_from'->>'clip_id')::bigint), "
            "(SELECT count(*) FROM modb.snippets s WHERE s.clip_id = v.clip_id), "
            "(SELECT DISTINCT s.pose_key FROM modb.snippets s WHERE s.clip_id = v.clip_id) = "
            "(SELECT DISTINCT modb.skeleton_pose_key(k.hierarchy) FROM modb.skeletons k "
            " WHERE k.id = v.skeleton_id) "
            "FROM modb.current_clips v JOIN modb.clips c ON c.id = v.clip_id "
            "JOIN modb.clip_versions cv USING (clip_id, version) "
            "WHERE v.collection IN ('cmu on bandai', 'bandai on cmu')"
        ).fetchall()
    assert len(rows) == 4
    for _, link, params, source_versions, snippets, same_pose in rows:
        assert link == params and link["clip_id"] > 0 and source_versions == 1
        assert snippets > 0 and same_pose


def test_retargeting_again_stores_nothing_and_bad_requests_say_why(pair):
    versions = "SELECT count(*) FROM modb.clip_versions"
    with psycopg.connect(pair) as conn:
        before = conn.execute(versions).fetchone()[0]
    r = run_modb(
        pair,
        "retarget",
        "cmu",
        "--to",
        "bandai/" + sorted(motions(pair, "bandai"))[0],
        "--collection",
        "cmu on bandai",
        "-q",
    )
    assert r.returncode == 0, r.stderr
    with psycopg.connect(pair) as conn:
        assert conn.execute(versions).fetchone()[0] == before
        for call, said in (
            ("SELECT modb.retarget(1000000000, 1)", "no clip"),
            ("SELECT modb.retarget(1, 1000000000)", "no skeleton"),
            ("SELECT modb.retarget(1, 1, fps => -3)", "fps must be"),
        ):
            with pytest.raises(psycopg.Error, match=said), conn.transaction():
                conn.execute(call)
