"""Processed data: a primitive's examples in a collection (its annotation segments of that name in
the clips' current versions) aligned in time to a reference example (align.py) and stored, one row
each, in modb.processed_data: what modb.align_primitive does in the server and a job worker does in
its own process (database.py runs the statements on either side).

Stale, never wrong: a row keeps the version and segment it was made from, so
modb.processed_data_status says when the clip has a newer version or the segment changed. Aligning
again keeps the rows that are still current when the reference is the same example with the same
settings, deletes the stale ones and aligns what is new; a new reference realigns everything.

Mirrored examples: where the skeleton has mirror pairs, the other side's segments (right_step for
left_step: "left" and "right" swapped in the name) are examples too, mirrored (mirror.py), so that a
model of either side learns from both feet."""

import json
import re

import numpy as np

from . import align as A
from . import mirror as mirroring
from . import resample
from . import retarget as R
from . import terminators as T
from .database import Statement, StoreError

MIN_EXAMPLES = 5
SETTINGS = {
    "cost": "mean distance of the standard joints' positions, first frames facing +Z at the origin",
    "steps": "one frame on in either or both",
    "time_function": "mean example frame per reference frame",
}

COLLECTION = Statement(
    "SELECT modb.collection_subtree($1) AS ids, modb.find_collection($1) AS id", ("text",)
)
# Every segment named one of $2 in the current versions of the collections' clips
EXAMPLES = Statement(
    """SELECT c.clip_id, c.version, c.fps, c.skeleton_id, a.seg::text AS segment,
              (a.seg->>'start')::int AS start, (a.seg->>'end')::int AS "end",
              a.seg->>'name' <> $2[1] AS mirrored
         FROM modb.current_clips c
         JOIN modb.clips k ON k.id = c.clip_id
         JOIN modb.clip_versions v USING (clip_id, version)
         CROSS JOIN LATERAL jsonb_array_elements(coalesce(v.meta->'annotations', '[]')) AS a(seg)
        WHERE k.collection_id = ANY ($1) AND a.seg->>'name' = ANY ($2)
        ORDER BY mirrored, c.clip_id, (a.seg->>'start')::int, (a.seg->>'end')::int""",
    ("bigint[]", "text[]"),
)
SKELETON = Statement(
    "SELECT hierarchy::text AS hierarchy, joint_map::text AS joint_map, "
    "mirror_pairs::text AS mirror_pairs "
    "FROM modb.skeletons WHERE id = $1",
    ("bigint",),
)
FRAMES = Statement(
    "SELECT rotations[$3:$4] AS rotations, translations[$3:$4] AS translations "
    "FROM modb.clip_versions WHERE clip_id = $1 AND version = $2",
    ("bigint", "int", "int", "int"),
)
# Two alignments of one primitive in one collection run one after the other.
LOCK = Statement(
    "SELECT pg_advisory_xact_lock(hashtext('modb align'), hashtext($1::text || '/' || $2))",
    ("bigint", "text"),
)
STORED = Statement(
    "SELECT id, clip_id, version, segment::text AS segment, mirrored, reference, "
    "settings::text AS settings "
    "FROM modb.processed_data WHERE collection_id = $1 AND primitive = $2",
    ("bigint", "text"),
)
DELETE = Statement("DELETE FROM modb.processed_data WHERE id = ANY ($1)", ("bigint[]",))
INSERT = Statement(
    """INSERT INTO modb.processed_data (collection_id, primitive, clip_id, version, segment,
                                        reference,
                                        n_frames, rotations, translations, time_function, sections,
                                        cost, settings, mirrored)
       VALUES ($1, $2, $3, $4, $5::jsonb, $6, $7, $8, $9, $10, $11, $12, $13::jsonb, $14)
       RETURNING id""",
    (
        "bigint",
        "text",
        "bigint",
        "int",
        "text",
        "boolean",
        "int",
        "real[]",
        "real[]",
        "float8[]",
        "int[]",
        "float8",
        "text",
        "boolean",
    ),
)


def _key(row):
    """An example's identity: its clip version, its segment (as JSON with sorted keys), mirrored."""
    segment = json.dumps(json.loads(row["segment"]), sort_keys=True)
    return (row["clip_id"], row["version"], segment, bool(row["mirrored"]))


SIDES = {"left": "right", "right": "left", "Left": "Right", "Right": "Left", "LEFT": "RIGHT",
         "RIGHT": "LEFT"}  # fmt: skip


def other_side(primitive):
    """The name of the primitive's mirror image (left_step -> right_step), or None."""
    words = re.split(r"(left|right|Left|Right|LEFT|RIGHT)", primitive)
    if len(words) == 1:
        return None
    return "".join(SIDES.get(w, w) for w in words)


class Alignment:
    """A primitive's examples in a collection, read and checked: plan() says what to do, then
    align_one() each example to do, and finish() what is stale."""

    def __init__(self, db, primitive, collection):
        self.db, self.primitive = db, primitive
        found = db.run(COLLECTION, [collection])[0]
        if not found["ids"]:
            raise StoreError(
                f'no collection "{collection}"',
                hint="modb.collection_path(id) names the stored ones",
                sqlstate="P0002",
            )
        self.collection_id = found["id"]
        names = [primitive] + [n for n in [other_side(primitive)] if n]
        self.examples = db.run(EXAMPLES, [found["ids"], names])
        if self.examples:
            self._read_skeleton(self.examples[0]["skeleton_id"])
            if not self.skeleton["mirror_pairs"]:
                self.examples = [e for e in self.examples if not e["mirrored"]]
        # sections are aligned onto the reference's: an example with another number of keyframes
        # than most (an action found as a reach among waves, say) is left out, not the primitive
        counts = [len(json.loads(e["segment"]).get("keyframes", [])) for e in self.examples]
        if counts:
            usual = max(set(counts), key=lambda c: (counts.count(c), -c))
            self.examples = [e for e, c in zip(self.examples, counts) if c == usual]
        n = len(self.examples)
        if n < MIN_EXAMPLES:
            raise StoreError(
                f'collection "{collection}" has {n} "{primitive}" segment{"" if n == 1 else "s"}: '
                "aligning "
                f"needs at least {MIN_EXAMPLES}",
                hint="annotate more (modb annotate --steps finds left_step and right_step)",
                sqlstate="22023",
            )
        for what in ("skeleton_id", "fps"):
            kinds = sorted({e[what] for e in self.examples})
            if len(kinds) > 1:
                raise StoreError(
                    f'the "{primitive}" examples of collection "{collection}" are on {len(kinds)} '
                    f"{'skeletons' if what == 'skeleton_id' else 'frame rates'} "
                    f"({', '.join(map(str, kinds))})",
                    hint="retarget them onto one skeleton at one rate first (modb retarget)",
                    sqlstate="22023",
                )
        self.fps = self.examples[0]["fps"]
        # the reference is a captured example, never a mirrored one
        own = [e for e in self.examples if not e["mirrored"]] or self.examples
        self.reference = own[A.reference_index([e["end"] - e["start"] + 1 for e in own])]
        self.reference_key = _key(self.reference)
        self.settings = {
            **SETTINGS,
            "reference": {
                "clip_id": self.reference["clip_id"],
                "version": self.reference["version"],
                "segment": json.loads(self.reference["segment"]),
            },
        }
        self._reference = None

    def _read_skeleton(self, skeleton_id):
        row = self.db.run(SKELETON, [skeleton_id])[0]
        h = json.loads(row["hierarchy"])
        self.joints = h["joints"]
        self.translated = h["translated"]
        self.skeleton = R.skeleton(h, json.loads(row["joint_map"]), None,
                                   json.loads(row["mirror_pairs"] or "[]"))  # fmt: skip
        try:
            self.std = T.standard_indices(
                [j["name"] for j in self.joints], json.loads(row["joint_map"])
            )
        except T.SkeletonMapError as e:
            raise StoreError(
                f"skeleton {skeleton_id}: {e}", hint="complete modb.skeletons.joint_map for it"
            ) from None

    def plan(self):
        """(examples to align, ids of stored rows to delete): only what changed when the reference
        and settings are those stored, else everything."""
        self.db.run(LOCK, [self.collection_id, self.primitive])
        stored = self.db.run(STORED, [self.collection_id, self.primitive])
        same = any(
            r["reference"]
            and _key(r) == self.reference_key
            and json.loads(r["settings"]) == self.settings
            for r in stored
        )
        current = {_key(e): e for e in self.examples}
        keep = {_key(r) for r in stored if same and _key(r) in current}
        drop = [r["id"] for r in stored if _key(r) not in keep]
        return [e for e in self.examples if _key(e) not in keep], drop

    def _frames(self, example):
        got = self.db.run(
            FRAMES,
            [example["clip_id"], example["version"], example["start"] + 1, example["end"] + 1],
        )[0]
        rotations = np.asarray(got["rotations"], dtype=np.float64)
        translations = (
            np.zeros((len(rotations), 0, 3))
            if got["translations"] is None
            else np.asarray(got["translations"], dtype=np.float64)
        )
        if example["mirrored"]:
            sk = self.skeleton
            rotations, translations = mirroring.mirror(
                sk["parents"], sk["offsets"], sk["end_sites"],
                mirroring.partner_index(sk["names"], sk["mirror_pairs"]),
                rotations, translations, sk["translated"],
            )  # fmt: skip
        return rotations, translations

    def _positions(self, rotations, translations):
        return A.canonical_positions(
            [j["parent"] for j in self.joints],
            [j["offset"] for j in self.joints],
            rotations,
            translations,
            self.translated,
            self.std,
            self.fps,
        )

    def _sections(self, example):
        keyframes = json.loads(example["segment"]).get("keyframes", [])
        return A.sections_of(keyframes, example["start"], example["end"])

    def align_one(self, example):
        """Aligns the example to the reference and stores its row; returns the row's id."""
        if self._reference is None:
            self._reference = self._positions(*self._frames(self.reference))
        rotations, translations = self._frames(example)
        try:
            times, costs = A.align(
                self._positions(rotations, translations),
                self._reference,
                self._sections(example),
                self._sections(self.reference),
            )
        except A.AlignError as e:
            raise StoreError(
                f"clip {example['clip_id']} frames {example['start']}-{example['end']}: {e}"
            ) from None
        aligned_rotations, aligned_translations = resample.sampled(rotations, translations, times)
        m = len(times)
        reference_sections = self._sections(self.reference)
        return self.db.run(
            INSERT,
            [
                self.collection_id,
                self.primitive,
                example["clip_id"],
                example["version"],
                example["segment"],
                _key(example) == self.reference_key,
                m,
                aligned_rotations.astype(np.float32).tolist(),
                aligned_translations.astype(np.float32).tolist()
                if aligned_translations.shape[1]
                else None,
                times.tolist(),
                reference_sections,
                float(sum(costs)),
                json.dumps(self.settings),
                bool(example["mirrored"]),
            ],
        )[0]["id"]


def align_primitive(db, primitive, collection, advance=None):
    """Aligns the primitive's examples in the collection (what changed since the last time, see the
    module's description) in the caller's transaction; returns (examples, aligned now, deleted)."""
    alignment = Alignment(db, primitive, collection)
    todo, drop = alignment.plan()
    db.run(DELETE, [drop])
    for k, example in enumerate(todo):
        alignment.align_one(example)
        if advance is not None:
            advance(k + 1, len(todo))
    return len(alignment.examples), len(todo), len(drop)
