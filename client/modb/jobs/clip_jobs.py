"""Jobs over clips, computed in the worker's process with the kernel (modb_kernel.retarget_clip,
edit_clips), each clip written in one transaction: a cancel stops before the next clip, a killed
worker loses only the clip it was writing, and a retry redoes nothing that was stored (a retargeting
finds its link, an edit its job's mark, a split its cuts)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import psycopg
from psycopg.rows import dict_row

from modb_kernel import (
    action_annotations,
    edit_clips,
    processed,
    retarget_clip,
    step_annotations,
)
from modb_kernel.database import StoreError

from modb.editing.script_notes import version_notes

from .kernel_database import WorkerDatabase
from .progress import JobProgress


class ClipJobError(ValueError):
    pass


def _words(error: StoreError) -> str:
    return f"{error} ({error.hint})" if error.hint else str(error)


def each_clip(
    conn: psycopg.Connection,
    progress: JobProgress,
    clips: list[int],
    stop_when_asked: Callable[[], None],
    one: Callable[[WorkerDatabase, int], dict[str, Any] | None],
) -> list[dict[str, Any]]:
    """one(db, clip) for each clip in a transaction of its own; what each made listed in the job's
    result as it goes, so a cancelled or failed job still says which clips it finished."""
    db, done = WorkerDatabase(conn), []
    progress.advance(0, len(clips), "clips")
    for k, clip in enumerate(clips):
        stop_when_asked()
        try:
            with conn.transaction():
                made = one(db, clip)
        except StoreError as e:
            raise ClipJobError(_words(e)) from None
        if made is not None:
            done.append(made)
            progress.partial({"clips": done})
        progress.advance(k + 1, len(clips), "clips")
    return done


def clip_now(conn: psycopg.Connection, clip: int) -> dict[str, Any]:
    """The clip's current version as a job's result lists it."""
    with conn.cursor(row_factory=dict_row) as cur:
        return cur.execute(
            "SELECT clip_id, collection || '/' || name AS clip, version, n_frames, fps, "
            "(SELECT count(*) FROM modb.snippets s WHERE s.clip_id = c.clip_id) AS snippets "
            "FROM modb.current_clips c WHERE clip_id = %s",
            [clip],
        ).fetchone()


def retarget(
    conn, progress, clips, stop_when_asked, skeleton, collection=None, fps=None, mirrored=False
) -> list[dict[str, Any]]:
    def one(db: WorkerDatabase, clip: int) -> dict[str, Any]:
        made = retarget_clip.retarget_clip(db, clip, skeleton, collection, fps, mirrored)
        return {"source": clip, **clip_now(conn, made)}

    return each_clip(conn, progress, clips, stop_when_asked, one)


def apply_edit_script(
    conn, progress, clips, stop_when_asked, script, job_id
) -> list[dict[str, Any]]:
    targets = list(dict.fromkeys(clips))
    try:  # every clip's result checked against the caps before any is edited, as in the server
        with conn.transaction():
            edits = edit_clips.Script(WorkerDatabase(conn), script)
            for clip in targets:
                edits.check_size(clip)
    except StoreError as e:
        raise ClipJobError(_words(e)) from None

    def one(db: WorkerDatabase, clip: int) -> dict[str, Any]:
        db.run(edit_clips.LOCK_CLIPS, [[clip]])
        edits.apply(clip, job=job_id)  # None: this job edited it before it was retried
        now = clip_now(conn, clip)
        return {**now, "notes": version_notes(conn, clip, now["version"])}

    return each_clip(conn, progress, targets, stop_when_asked, one)


def split_by_annotation(
    conn, progress, clips, stop_when_asked, annotation=None, collection=None
) -> list[dict[str, Any]]:
    def one(db: WorkerDatabase, clip: int) -> dict[str, Any]:
        try:
            with conn.cursor(row_factory=dict_row) as cur:
                cuts = cur.execute(
                    "SELECT clip_id, name, segment, first_frame, last_frame, created "
                    "FROM modb.split_by_annotation(%s, %s, %s)",
                    [clip, annotation, collection],
                ).fetchall()
        except psycopg.Error as e:
            raise StoreError(e.diag.message_primary or str(e), e.diag.message_hint) from None
        return {"source": clip, "cuts": cuts}

    return each_clip(conn, progress, clips, stop_when_asked, one)


def annotate_steps(conn, progress, clips, stop_when_asked) -> list[dict[str, Any]]:
    def one(db: WorkerDatabase, clip: int) -> dict[str, Any]:
        version, made = step_annotations.annotate(db, clip)
        counts = {n: 0 for n in ("left_step", "right_step")}
        for s in made:
            counts[s["name"]] = counts.get(s["name"], 0) + 1
        return {"clip_id": clip, "version": version, "steps": counts}

    return each_clip(conn, progress, clips, stop_when_asked, one)


def annotate_action(conn, progress, clips, stop_when_asked, action) -> list[dict[str, Any]]:
    def one(db: WorkerDatabase, clip: int) -> dict[str, Any]:
        version, made = action_annotations.annotate(db, clip, action)
        return {"clip_id": clip, "version": version, "segments": made}

    return each_clip(conn, progress, clips, stop_when_asked, one)


def align(conn, progress, stop_when_asked, primitive, collection) -> dict[str, Any]:
    """The primitive's examples aligned in one transaction (a cancel leaves the rows as they
    were)."""

    def advance(done: int, total: int) -> None:
        stop_when_asked()
        progress.advance(done, total, "examples")

    try:
        with conn.transaction():
            examples, aligned, deleted = processed.align_primitive(
                WorkerDatabase(conn), primitive, collection, advance
            )
    except StoreError as e:
        raise ClipJobError(_words(e)) from None
    return {"primitive": primitive, "collection": collection, "examples": examples,
            "aligned": aligned, "deleted": deleted}  # fmt: skip
