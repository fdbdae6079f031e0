"""The benchmark's speed-resampled clips (modb.bench.resampled.at_speed) on a real capture: whole
steps keep the captured frames, half steps lie halfway between them (rotation angles by scipy,
positions by bvhio-checked forward kinematics)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.data import mocap

from modb.bench.resampled import at_speed
from modb.loader.bvh import read_bvh


@pytest.fixture(scope="module")
def walk():
    return read_bvh(str(mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")), "auto")


def _rotations(q: np.ndarray) -> Rotation:
    return Rotation.from_quat(q.reshape(-1, 4)[:, [1, 2, 3, 0]])


def test_twice_as_fast_keeps_every_other_frame(walk):
    fast = at_speed(walk, 2.0)
    assert fast.n_frames == (walk.n_frames - 1) // 2 + 1 and fast.fps == walk.fps
    assert np.abs(fast.rotations - walk.rotations[::2]).max() < 1e-6
    assert np.abs(fast.translations - walk.translations[::2]).max() < 1e-9


def test_half_speed_puts_a_frame_halfway_between_each_pair(walk):
    slow = at_speed(walk, 0.5)
    assert slow.n_frames == 2 * walk.n_frames - 1
    between, before, after = (
        _rotations(q) for q in (slow.rotations[1::2], walk.rotations[:-1], walk.rotations[1:])
    )
    apart = (before.inv() * after).magnitude()
    assert np.abs((before.inv() * between).magnitude() - apart / 2).max() < 1e-6
    assert np.abs((between.inv() * after).magnitude() - apart / 2).max() < 1e-6
    assert np.all(slow.rotations[..., 0] >= 0)  # the model's sign convention
    mid = (walk.world_positions()[:-1] + walk.world_positions()[1:]) / 2
    # 1 cm: rotations do not interpolate linearly
    assert np.abs(slow.world_positions()[1::2] - mid).max() < 0.01


def test_a_speed_must_be_positive(walk):
    with pytest.raises(ValueError, match="positive"):
        at_speed(walk, 0.0)
