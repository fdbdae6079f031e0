"""Mirroring on real rigs: one frame convention per skeleton, an involution, positions reflected
exactly.

Bandai's Maya-style rig is the hard case: every joint has translation channels, the right limbs'
axes are the left ones' negated, and the spine's frames twist by 90 degrees between hips and chest.
CMU's ASF rig has world-aligned frames (S = diag(-1, 1, 1) everywhere). The tests on the database
(after them) check the result where it matters: mirrored snippets turn the other way, are placed
where the database says, and their terminators are poses the captured walk takes."""

from __future__ import annotations

import numpy as np
import pytest
from support.commands import run_modb
from support.data import mocap

from modb.database.connection import connect
from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb.demo.data import locomotion_files
from modb.motion import Motion
from modb_kernel import kinematics, mirror, quaternion


def _args(motion: Motion):
    sk = motion.skeleton
    partner = mirror.partner_index(sk.names, sk.mirror_pairs)
    return (
        sk.parents,
        sk.offsets,
        [j.end_site for j in sk.joints],
        partner,
        motion.rotations,
        motion.translations,
        sk.translated,
    )


def _clip(name: str) -> Motion:
    if name == "bandai-walk":
        return read_bvh(str(mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")))
    return read_amc(
        str(mocap("cmu", "131", f"{name}.amc")), read_asf(str(mocap("cmu", "131", "131.asf")))
    )


def test_one_convention_for_every_locomotion_clip_of_a_skeleton():
    """Each clip is mirrored on its own, so the twists taken from it must agree across clips, or the
    mirror images of different clips could not follow each other: all of Bandai dataset 2's
    locomotion."""
    files = locomotion_files(mocap("bandai-2-dev", "data"))
    assert len(files) > 400
    conventions = {}
    for path in files:
        motion = read_bvh(str(path))
        key = np.round(mirror.clip_reflections(*_args(motion)), 6).tobytes()
        conventions.setdefault(key, []).append(path.name)
    assert len(conventions) == 1, {k[:8]: v[:3] for k, v in conventions.items()}


@pytest.mark.parametrize("clip", ["bandai-walk", "131_01"])
def test_mirroring_twice_gives_the_clip_back(clip):
    motion = _clip(clip)
    parents, offsets, ends, partner, rotations, translations, translated = _args(motion)
    once = mirror.mirror(parents, offsets, ends, partner, rotations, translations, translated)
    twice = mirror.mirror(parents, offsets, ends, partner, *once, translated)
    assert quaternion.angle_between(twice[0], rotations).max() < 1e-9
    assert np.abs(np.asarray(twice[1]) - translations).max() < 1e-12


@pytest.mark.parametrize("clip, tolerance", [("bandai-walk", 1e-9), ("131_01", 0.04)])
def test_mirrored_positions_are_the_captured_ones_reflected(clip, tolerance):
    """Exact for Bandai's symmetric skeleton; CMU 131's captured skeleton differs by up to a few cm
    between sides (its arms; the neck leans 7 degrees), which mirroring keeps."""
    motion = _clip(clip)
    parents, offsets, ends, partner, rotations, translations, translated = _args(motion)
    mirrored = mirror.mirror(parents, offsets, ends, partner, rotations, translations, translated)
    captured_p, _ = kinematics.world_transforms(
        parents, offsets, rotations, translations, translated
    )
    mirrored_p, _ = kinematics.world_transforms(parents, offsets, *mirrored, translated)
    assert np.abs(captured_p[:, partner] * [-1, 1, 1] - mirrored_p).max() < tolerance


def test_mirror_images_turn_the_other_way(cmu):
    with connect(cmu) as conn:
        rows = conn.execute(
            "SELECT a.net_translation, b.net_translation, a.net_heading, b.net_heading FROM "
            "modb.snippets a "
            "JOIN modb.snippets b USING (clip_id, version, first_frame) WHERE NOT a.mirrored AND "
            "b.mirrored"
        ).fetchall()
    a = np.array([r[0] for r in rows])
    b = np.array([r[1] for r in rows])
    # CMU 131's captured skeleton is not exactly symmetric (arms differ by up to ~1.5 cm): mm-level
    # agreement.
    assert np.abs(b - a * [-1, 1, 1]).max() < 0.01
    turn_error = np.abs(np.array([r[3] for r in rows]) + np.array([r[2] for r in rows]))
    # the hip axis feels the asymmetry most
    assert np.median(turn_error) < 0.002 and turn_error.max() < 0.1


def test_a_new_version_keeps_its_mirror_images(fresh_db, db):
    amc = mocap("cmu", "131", "131_01.amc")
    assert run_modb(fresh_db, "load", amc, "--mirror").returncode == 0
    # a new version, no --mirror
    assert run_modb(fresh_db, "load", amc, "--fps", "60").returncode == 0
    rows = db.execute(
        "SELECT version, mirrored, count(*) FROM modb.snippets GROUP BY 1, 2 ORDER BY 1, 2"
    ).fetchall()
    assert [(v, m) for v, m, _ in rows] == [(2, False), (2, True)] and rows[0][2] == rows[1][2]


def test_mirrored_snippets_are_placed_where_the_database_says(cmu):
    """The client mirrors a clip's frames itself (source_frames.py); the database measured the
    mirrored snippets' travel and turn when it built them. A strip that starts on a mirrored snippet
    (CMU 131, 120 fps) must end each snippet where the chain's arithmetic on those stored figures
    puts it."""
    from modb.synthesis.avatar import Settings
    from modb.synthesis.synth import synthesize

    with connect(cmu) as conn:
        start = conn.execute(
            "SELECT min(id) FROM modb.snippets WHERE mirrored AND first_frame = 120"
        ).fetchone()[0]
        result = synthesize(conn, [(0.0, 4.0), (3.0, 0.0)], 4.0, Settings(), start_snippet=start)
    assert result.chain[0].mirrored and sum(c.mirrored for c in result.chain) >= 2
    sk = result.strip.skeleton
    pelvis = result.strip.world_positions()[:, sk.index(sk.joint_map["pelvis"])]
    for c in result.chain:
        assert abs(pelvis[c.end_frame, 0] - c.end.position[0]) < 1e-3
        assert abs(pelvis[c.end_frame, 2] - c.end.position[2]) < 1e-3


def test_mirrored_terminators_are_poses_the_captured_walk_takes(fresh_db, db):
    """A mirrored walk is still a walk: every mirrored terminator must be close, joint by joint, to
    some captured terminator of the same clip (half a cycle away), so that mirrored and captured
    snippets can follow each other. Bandai's Maya-style rig needs per-joint frame reflections (the
    right limbs' axes are the left ones' negated, the spine's frames twist); a wrong one leaves
    positions exact but turns a joint's rotation up to 180 degrees away from any captured one, which
    this catches. Checked without the mirroring code: positions by reflecting the captured ones,
    rotations by a brute-force nearest search."""
    from modb_kernel.joints import STANDARD_JOINTS

    walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    assert run_modb(fresh_db, "load", walk, "--mirror").returncode == 0
    terms = {
        m: [
            np.array(column)
            for column in zip(
                *db.execute(
                    "SELECT positions, rotations FROM modb.terminators WHERE mirrored = %s ORDER "
                    "BY frame",
                    [m],
                ).fetchall()
            )
        ]
        for m in (False, True)
    }
    (captured_p, captured_r), (mirrored_p, mirrored_r) = terms[False], terms[True]
    partner = [
        STANDARD_JOINTS.index(n.replace("left", "~").replace("right", "left").replace("~", "right"))
        for n in STANDARD_JOINTS
    ]
    captured_p = captured_p.reshape(len(captured_p), 19, 3)
    assert (
        np.abs(captured_p[:, partner] * [-1, 1, 1] - mirrored_p.reshape(captured_p.shape)).max()
        < 1e-4
    )
    a, b = captured_r.reshape(-1, 19, 4), mirrored_r.reshape(-1, 19, 4)
    cos = np.abs(np.einsum("fjk,gjk->fgj", b, a))  # every mirrored frame against every captured one
    nearest = np.degrees(2 * np.arccos(np.clip(cos.max(axis=1), 0, 1)))  # (mirrored frames, joints)
    assert np.median(nearest, axis=0).max() < 10, dict(
        zip(STANDARD_JOINTS, np.median(nearest, axis=0).round(1))
    )


def test_mirrored_snippets_can_follow_captured_ones(fresh_db, db):
    """With two walks and their mirror images, a captured snippet's nearest mirrored continuation
    (the default profile's continuity ratio) is typically no farther than its nearest one from the
    other captured walk: the mirror images add choice instead of forming a pool of their own."""
    walks = [
        mocap("bandai-1", "data", f"dataset-1_walk_{style}_001.bvh")
        for style in ("active", "normal")
    ]
    assert run_modb(fresh_db, "load", *walks, "--mirror").returncode == 0
    rows = db.execute(
        "WITH prev AS (SELECT s.id, s.clip_id, t FROM modb.snippets s JOIN modb.terminators t ON "
        "t.id = s.end_terminator "
        "               WHERE NOT s.mirrored AND s.id % 25 = 0), "
        "nearest AS (SELECT p.id, c.mirrored, c.clip_id = p.clip_id AS same_clip, "
        "                   min(modb.continuity_ratio(p.t, b, modb.match_plan('default'))) AS "
        "ratio "
        "              FROM prev p, modb.snippets c JOIN modb.terminators b ON b.id = "
        "c.begin_terminator "
        "             GROUP BY 1, 2, 3) "
        "SELECT mirrored, same_clip, percentile_cont(0.5) WITHIN GROUP (ORDER BY ratio) FROM "
        "nearest "
        "GROUP BY 1, 2"
    ).fetchall()
    median = {(m, same): r for m, same, r in rows}
    assert (
        median[(True, True)] <= median[(False, False)]
        and median[(True, False)] <= 1.5 * median[(False, False)]
    ), median
