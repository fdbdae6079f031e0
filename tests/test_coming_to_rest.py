"""Coming to rest (issue 24): after the last goal the avatar slows and stands with stopping and
standing motion from the data (CMU 131 has some), in modb.synthesize and the Avatar alike; a new
goal sets it walking again; data without such motion (Bandai's locomotion takes) is said to have
none and the avatar keeps walking. Speeds from scipy's kinematics of the strip."""

from __future__ import annotations

import numpy as np
from support.databases import COLLECTION
from support.snippet_oracle import motion_world

from modb.database.connection import connect
from modb.synthesis.avatar import Avatar, Settings
from modb.synthesis.synth import strip_motion, synthesize

GOAL = (0.0, 3.0)


def pelvis_path(motion) -> np.ndarray:
    sk = motion.skeleton
    return motion_world(motion)[0][:, sk.index(sk.joint_map["pelvis"])]


def ground_speed(path: np.ndarray, fps: float) -> np.ndarray:
    """m/s over the ground, averaged over a quarter second."""
    step = np.linalg.norm(np.diff(path[:, [0, 2]], axis=0), axis=1) * fps
    width = max(1, int(fps / 4))
    return np.convolve(step, np.ones(width) / width, mode="same")


def test_after_the_last_goal_it_stops_within_two_seconds_and_stays(cmu):
    with connect(cmu) as conn:
        sql = [
            r[0]
            for r in conn.execute("SELECT snippet_id FROM modb.synthesize(%s, 40)", [[list(GOAL)]])
        ]
        result = synthesize(conn, [GOAL], 16.0, Settings(collection="cmu/131"))
    chain = [c.snippet_id for c in result.chain]
    assert chain == sql[: len(chain)]  # the same rule in SQL and Python
    fps = result.strip.fps
    path = pelvis_path(result.strip)
    arrived = next(c.end_frame for c in result.chain if c.reached)
    assert arrived < 8 * fps
    speed = ground_speed(path, fps)
    after = speed[arrived + int(2 * fps) : -int(fps / 4)]
    assert len(after) > 5 * fps and after.max() < 0.1, after.max()
    distance = np.hypot(path[arrived:, 0] - GOAL[0], path[arrived:, 2] - GOAL[1])
    assert distance.max() < 0.75
    # standing is motion, not a frozen frame
    assert np.abs(np.diff(result.strip.rotations[arrived:], axis=0)).max(axis=(1, 2)).min() > 0


def test_a_new_goal_sets_it_walking_again_toward_it(cmu):
    new_goal = (3.0, 3.0)
    with connect(cmu) as conn:
        avatar = Avatar(conn, goals=[GOAL], settings=Settings(collection="cmu/131"))
        frames, resting_from, moved_at = [], None, None
        for frame in avatar.frames():
            frames.append(frame)
            fps = avatar.choices[-1].fps
            if resting_from is None and any(c.reached for c in avatar.choices):
                resting_from = frame.index
            if (
                moved_at is None
                and resting_from is not None
                and frame.index > resting_from + 3 * fps
            ):
                avatar.set_goal(new_goal)
                moved_at = frame.index
            if moved_at is not None and frame.index > moved_at + 3 * fps:
                break
        motion = avatar.library.get(avatar.choices[0].clip_id, avatar.choices[0].version, False)
    strip = strip_motion(frames, motion.motion, "walk")
    path = pelvis_path(strip)
    speed = ground_speed(path, fps)
    assert speed[moved_at - int(fps) : moved_at].max() < 0.1  # it stood
    assert speed[moved_at + int(2 * fps) : moved_at + int(3 * fps)].min() > 0.3  # it walks
    # Chosen for the new goal: from 0.29.0 the standing snippet playing is chosen again toward it
    # (a start from the snippet before). Where the walk then goes is the data's: on CMU 131 the
    # starts from this spot lead away before they turn (0.28.0's avatar too: 4.7 m from the goal
    # 3 s on, from 3.1), so only that it walks is asserted, above.
    assert any(c.target == new_goal for c in avatar.choices)


def test_without_standing_motion_it_says_so_and_keeps_walking(locomotion):
    with connect(locomotion) as conn:
        (standing,) = conn.execute(
            "SELECT count(*) FROM modb.snippets s WHERE modb.end_speed(s.id) < modb.rest_speed() "
            "AND s.collection_id = ANY (modb.collection_subtree(%s))",
            [COLLECTION],  # the Bandai clips synthesis draws from (not CMU's, beside them)
        ).fetchone()
        result = synthesize(conn, [GOAL], 10.0, Settings())
    assert standing == 0
    assert any("has no motion that stops or stands" in n for n in result.notes), result.notes
    arrived = next(c.end_frame for c in result.chain if c.reached)
    assert ground_speed(pelvis_path(result.strip), result.strip.fps)[arrived:].min() > 0.1
