"""Values below float4's range in a clip's terminators are stored as 0, not refused: Bandai's
dataset-1_bow_normal_001 at 0.8x speed (`modb bench scale`'s resampled copies) had 3.8e-51 in a
terminator, and before 0.10.0 its snippets could not be built."""

from __future__ import annotations

from support.data import mocap

from modb.bench.resampled import at_speed
from modb.database.connection import connect
from modb.loader.bvh import read_bvh
from modb.loader.ingest import store_motion


def test_a_clip_whose_terminators_underflow_float4_gets_its_snippets(db):
    motion = at_speed(read_bvh(str(mocap("bandai-1", "data", "dataset-1_bow_normal_001.bvh"))), 0.8)
    with connect(db.info.dsn) as conn:
        added = store_motion(conn, motion, "bow", "0.8x", snippets=True, mirrored=True).snippets
        assert added > 0
        (smallest,) = conn.execute(
            "SELECT min(abs(p)) FILTER (WHERE p <> 0) FROM modb.terminators, "
            "unnest(positions || rotations || velocities || angular_velocities) AS p"
        ).fetchone()
        assert smallest >= 1e-45  # float4's least denormal: the tiny ones became 0
