"""Samples of a stored motion model (modb.models, kind motion_primitive): what modb.sample_motion
returns, the same in the server and in the client, which calls that function."""

import json

import numpy as np

from . import memory, motion_model
from .database import Statement, StoreError

KIND = "motion_primitive"
MAX_SAMPLES = 1000
MODEL = Statement(
    """SELECT id, version, data::text AS data FROM modb.models
        WHERE name = $1 AND kind = 'motion_primitive' AND ($2::int IS NULL OR version = $2)
        ORDER BY version DESC LIMIT 1""",
    ("text", "int"),
)


def load(db, name, version=None):
    """(id, version, model document) of the model's version (the latest when None)."""
    if name is None:
        raise StoreError("model is NULL: name a motion model", sqlstate="22004",
                         hint="modb model list names them")  # fmt: skip
    rows = db.run(MODEL, [name, version])
    if not rows:
        which = "" if version is None else f" version {version}"
        raise StoreError(
            f'no motion model "{name}"{which}',
            hint="modb model list names them; modb model build makes one",
            sqlstate="P0002",
        )
    return rows[0]["id"], rows[0]["version"], json.loads(rows[0]["data"])


def sample_motion(db, name, n, seed, version=None):
    """[(sample, fps, n_frames, rotations, translations)]: n motions drawn from the model with the
    seed, each starting at the origin facing +Z."""
    if n is None or not 1 <= n <= MAX_SAMPLES:
        raise StoreError(f"n is {n}: ask for 1 to {MAX_SAMPLES} samples", sqlstate="22023")
    if seed is None or seed < 0:
        raise StoreError(f"seed is {seed}: give a whole number >= 0", sqlstate="22023")
    _, _, model = load(db, name, version)
    out = []
    drawn = motion_model.sample(model, n, seed, db.check_interrupts)
    for k, (rotations, translations, _) in enumerate(drawn):
        out.append((
            k + 1,
            model["fps"],
            len(rotations),
            rotations.astype(np.float32).tolist(),
            translations.astype(np.float32).tolist() if translations.shape[1] else None,
        ))  # fmt: skip
    memory.release()  # the drawn frames are garbage now: their memory goes back to the system
    return out
