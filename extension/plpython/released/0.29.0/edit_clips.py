"""A stored edit script applied to stored clips, each result a new version cut into snippets: what
modb.apply_edit_script does in the server and a job worker does in its own process (database.py runs
the statements on either side; edits.py does the editing)."""

import json

import numpy as np

from . import edits as E
from . import memory
from . import retarget as R
from . import snippet_cut
from . import terminators as T
from .database import Statement, StoreError

SCRIPT = Statement(
    "SELECT commands::text AS commands FROM modb.edit_scripts WHERE name = $1", ("text",)
)
# The clips' rows locked in id order, as every writer of a clip's versions does, so two scripts on
# one
# clip run one after the other (each on the other's result) and never deadlock.
LOCK_CLIPS = Statement(
    "SELECT FROM modb.clips WHERE id = ANY ($1) ORDER BY id FOR NO KEY UPDATE", ("bigint[]",)
)
SIZE = Statement(
    """SELECT v.version, v.fps, v.n_frames, jsonb_array_length(s.hierarchy->'joints') AS joints,
              coalesce(jsonb_array_length(s.hierarchy->'translated'), 0) AS translated
         FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.clip_id = $1 ORDER BY v.version DESC LIMIT 1""",
    ("bigint",),
)
SKELETON_SIZE = Statement(
    """SELECT jsonb_array_length(hierarchy->'joints') AS joints,
              coalesce(jsonb_array_length(hierarchy->'translated'), 0) AS translated
         FROM modb.skeletons WHERE id = $1""",
    ("bigint",),
)
CLIP = Statement(
    """SELECT v.version, v.fps, v.rotations, v.translations, v.meta::text AS meta,
           v.load_params::text AS load_params,
              s.id AS skeleton_id, s.hierarchy::text AS hierarchy, s.joint_map::text AS joint_map,
              s.joint_axes::text AS joint_axes, s.mirror_pairs::text AS mirror_pairs,
              EXISTS (SELECT FROM modb.snippet_sources ss WHERE ss.clip_id = v.clip_id AND
                  ss.mirrored) AS mirrored
         FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
        WHERE v.clip_id = $1 ORDER BY v.version DESC LIMIT 1""",
    ("bigint",),
)
SKELETON = Statement(
    """SELECT s.hierarchy::text AS hierarchy, s.joint_map::text AS joint_map, s.joint_axes::text
           AS joint_axes,
              s.mirror_pairs::text AS mirror_pairs,
              (SELECT v.rotations FROM modb.current_clips c JOIN modb.clip_versions v USING
                  (clip_id, version)
                WHERE c.skeleton_id = s.id ORDER BY c.clip_id LIMIT 1) AS rotations,
              (SELECT v.translations FROM modb.current_clips c JOIN modb.clip_versions v USING
                  (clip_id, version)
                WHERE c.skeleton_id = s.id ORDER BY c.clip_id LIMIT 1) AS translations
         FROM modb.skeletons s WHERE s.id = $1""",
    ("bigint",),
)
ADD_VERSION = Statement(
    """INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations,
           translations, load_params, meta)
       VALUES ($1, $2, $3, $4, $5, $6, $7::jsonb, $8::jsonb) RETURNING version""",
    ("bigint", "bigint", "float8", "int", "real[]", "real[]", "text", "text"),
)
COUNT = Statement("SELECT count(*) AS n FROM modb.snippets WHERE clip_id = $1", ("bigint",))


def _frames(rotations, translations):
    r = np.asarray(rotations, dtype=np.float64)
    return r, (
        np.zeros((r.shape[0], 0, 3))
        if translations is None
        else np.asarray(translations, dtype=np.float64)
    )


def _skeleton(row, skeleton_id):
    try:
        sk = R.skeleton(
            json.loads(row["hierarchy"]),
            json.loads(row["joint_map"]),
            json.loads(row["joint_axes"]),
            json.loads(row["mirror_pairs"]),
        )
    except (TypeError, ValueError) as e:  # joint_axes stored before 0.17.0 checked them
        raise StoreError(
            f"skeleton {skeleton_id} has joint_axes that are not numbers ({e})",
            hint="store them again, or set them to {} to derive them anew",
        ) from None
    sk["id"] = skeleton_id
    return sk


def _clip(row):
    r, t = _frames(row["rotations"], row["translations"])
    return {
        "skeleton": _skeleton(row, row["skeleton_id"]),
        "fps": row["fps"],
        "rotations": r,
        "translations": t,
    }


class Script:
    """A stored script, read and checked, ready to apply to clips."""

    def __init__(self, db, name):
        found = db.run(SCRIPT, [name])
        if not found:
            raise StoreError(
                f'no edit script "{name}"',
                hint="SELECT name FROM modb.edit_scripts lists them",
                sqlstate="P0002",
            )
        self.db, self.name, self.commands = db, name, json.loads(found[0]["commands"])
        problems = E.script_errors(self.commands)
        if problems:  # a row stored before 0.17.0 checked scripts
            raise StoreError(
                f'edit script "{name}" cannot run: {"; ".join(problems)}',
                hint="save it again with commands that modb.edit_scripts describes",
            )

    def check_size(self, clip_id):
        """The result's frames, bytes and rate from the script's parameters, refused before any
        work."""
        rows = self.db.run(SIZE, [clip_id])
        if not rows:
            raise StoreError(
                f"no clip {clip_id} with a version",
                hint="modb.current_clips lists the stored clips",
                sqlstate="P0002",
            )
        size = rows[0]
        n_frames, fps, largest = E.result_frames(self.commands, size["n_frames"], size["fps"])
        joints, translated = size["joints"], size["translated"]
        for skeleton in {
            c["skeleton"] for c in self.commands if c["op"] == "retarget"
        }:  # the largest
            other = self.db.run(SKELETON_SIZE, [skeleton])
            if other:
                joints, translated = (
                    max(joints, other[0]["joints"]),
                    max(translated, other[0]["translated"]),
                )
        what = "the result" if largest <= n_frames else "a step"
        try:
            E.check_result_size(
                largest, joints, translated, f'edit script "{self.name}" on clip {clip_id}: {what}'
            )
        except E.EditError as e:
            raise StoreError(
                str(e), hint="the caps are in docs/reference.md (Limits)", sqlstate="54000"
            ) from None
        slow = T.snippet_rate_error(fps)
        if slow:
            raise StoreError(
                f'edit script "{self.name}" on clip {clip_id}: the result at {fps:g} fps: {slow}',
                hint="resample to a higher rate in the script",
                sqlstate="22023",
            )

    def _fetch(self, clip_id):
        if not isinstance(clip_id, int):
            return None
        rows = self.db.run(CLIP, [clip_id])
        return _clip(rows[0]) if rows else None

    def _fetch_skeleton(self, skeleton_id):
        if not isinstance(skeleton_id, int):
            return None
        rows = self.db.run(SKELETON, [skeleton_id])
        if not rows:
            return None
        reference = (
            None
            if rows[0]["rotations"] is None
            else _frames(rows[0]["rotations"], rows[0]["translations"])
        )
        return _skeleton(rows[0], skeleton_id), reference

    def apply(self, clip_id, job=None):
        """A new version of the clip, cut into snippets: (clip_id, version, n_frames, snippets).
        `job`: the job applying it, recorded with the version; a clip whose current version that
        job made already is left as it is (a retried job does not edit it twice)."""
        row = self.db.run(CLIP, [clip_id])[0]
        if (
            job is not None
            and json.loads(row["load_params"]).get("edit_script", {}).get("job") == job
        ):
            return None
        clip = _clip(row)
        try:
            edited = E.apply(clip, self.commands, self._fetch, self._fetch_skeleton)
        except E.EditError as e:
            raise StoreError(
                f'edit script "{self.name}" on clip {clip_id}: {e}',
                hint="fix the script (modb.edit_scripts)",
            ) from None
        meta = json.loads(row["meta"])
        n_frames = edited["rotations"].shape[0]
        if n_frames != clip["rotations"].shape[0]:
            meta.pop("annotations", None)  # frame numbers: they stay with the version they describe
        record = {"name": self.name, "commands": self.commands, "from_version": row["version"]}
        if job is not None:
            record["job"] = job
        translations = edited["translations"]
        skeleton_id, fps, mirrored = edited["skeleton"]["id"], edited["fps"], bool(row["mirrored"])
        rotations = edited["rotations"].astype(np.float32).tolist()
        translations = translations.astype(np.float32).tolist() if translations.shape[1] else None
        del row, clip, edited  # the float64 frames: only the lists the insert needs stay
        made = self.db.run(
            ADD_VERSION,
            [
                clip_id,
                skeleton_id,
                fps,
                n_frames,
                rotations,
                translations,
                json.dumps({"edit_script": record}),
                json.dumps(meta),
            ],
        )[0]["version"]
        del rotations, translations
        snippet_cut.cut_clip(self.db, clip_id, mirrored)
        memory.release()  # a large edit's frames are garbage: their memory goes back to the system
        return clip_id, made, n_frames, self.db.run(COUNT, [clip_id])[0]["n"]


def apply_script(db, name, clips):
    """Applies the script to each clip (each once, in the order given), every size checked before
    any work; one call, so one transaction in the server: a failing clip stores none."""
    script = Script(db, name)
    targets = list(dict.fromkeys(c for c in (clips or []) if c is not None))
    db.run(LOCK_CLIPS, [targets])
    for clip_id in targets:
        script.check_size(clip_id)
    return [script.apply(clip_id) for clip_id in targets]
