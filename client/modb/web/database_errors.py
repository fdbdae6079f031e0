"""The database's errors as HTTP answers, in one place: the message without the driver's prefixes
(`plpy.Error:`, `spiexceptions.CheckViolation:`, `ERROR:`), a broken table rule said in the user's
words, and the status: 404 for what is not there, 409 for what already is, 413 for a result past
the caps, 400 for data the database refuses, 503 with Retry-After for what may work a moment later
(a deadlock, a serialization failure, a lock not granted, two writers numbering the same version,
a database that is unreachable). Never a 500 for a request's content."""

from __future__ import annotations

import re

import psycopg
from psycopg import errors

RETRY_AFTER_S = 2
PREFIX = re.compile(r"^\s*(?:(?:plpy\.\w+|spiexceptions\.\w+|ERROR|FATAL)\s*:\s*)+")

# A table rule a request can break, in the words of the one who sent it.
CHECKS = {
    "snippet_sources_window_frames_check": "the clip would have too few frames at this frame "
    "rate to cut into snippets: choose a higher frame rate",
    "clip_versions_translations_finite_check": "the result's positions are not finite numbers "
    "(a skeleton whose bones all have zero length has no size to scale to)",
    "clip_versions_rotations_unit_check": "the result's rotations are not unit quaternions",
    "clip_versions_fps_check": "the frame rate must be a finite number greater than 0",
    "clip_versions_n_frames_check": "the result has no frames",
    "clip_versions_meta_check": "an annotation lies outside the clip's frames",
    "skeletons_joint_map_check": "the joint map must map standard joint names onto joints of "
    "the skeleton (GET /api/skeletons/ID lists both)",
    "skeletons_mirror_pairs_check": "each mirror pair must name two joints of the skeleton",
    "skeletons_joint_axes_check": "joint_axes must name joints of the skeleton, and its pose give "
    "one [w, x, y, z] per joint",
    "collections_name_check": "a collection's name cannot hold '/'",
}
# Unique keys the server numbers itself: two writers meeting there raced, and the later one may
# simply try again. Any other unique key is a name the client chose that is taken (409).
RACED_KEYS = {
    "clip_versions_pkey",
    "snippet_sources_pkey",
    "terminators_clip_id_version_mirrored_frame_key",
}
TRANSIENT = (errors.TransactionRollback, errors.LockNotAvailable)  # deadlock, serialization


def without_prefixes(text: str) -> str:
    """'plpy.Error: no clip 7' -> 'no clip 7' (the driver's names mean nothing to a user)."""
    return PREFIX.sub("", text).strip()


def message(e: psycopg.Error) -> str:
    """The database's message and hint, without the driver's prefixes."""
    text = without_prefixes(e.diag.message_primary or str(e).split("\n", 1)[0])
    hint = without_prefixes(e.diag.message_hint or "")
    return f"{text} ({hint})" if hint else text


def is_transient(e: psycopg.Error) -> bool:
    """Whether the same request may well work a moment later (the rows were held or raced)."""
    return isinstance(e, TRANSIENT) or (
        isinstance(e, errors.UniqueViolation) and e.diag.constraint_name in RACED_KEYS
    )


def is_connection_lost(e: psycopg.Error) -> bool:
    """Whether the connection itself failed (no SQLSTATE, a connection exception, the server
    shutting down), not a statement the server refused: psycopg counts both as OperationalError
    (a result past a cap, 54000, among them), and only the first may work again on another."""
    state = e.sqlstate
    return isinstance(e, psycopg.OperationalError) and (
        state is None or state.startswith("08") or state in ("57P01", "57P02", "57P03")
    )


def answer(e: psycopg.Error) -> tuple[int, str]:
    """(HTTP status, message) for a database error raised while answering a request: not one of
    a connection that broke (the app asks whether the server is there)."""
    constraint = e.diag.constraint_name
    if is_transient(e):
        return 503, (
            f"another write to the same rows got there first ({e.sqlstate}): nothing was "
            f"stored; try again in {RETRY_AFTER_S} s"
        )
    if isinstance(e, errors.UniqueViolation):
        return 409, f"already exists: {message(e)}"
    if isinstance(e, errors.CheckViolation):
        words = CHECKS.get(constraint or "")
        if words:
            return 400, f"refused: {words} (rule {constraint} of {e.diag.table_name})"
        return 400, f"refused: {message(e)}"
    if isinstance(e, errors.NoDataFound):
        return 404, message(e)
    if isinstance(e, errors.ProgramLimitExceeded):  # a result past the stated caps
        return 413, message(e)
    if isinstance(e, errors.DependentObjectsStillExist):
        return 409, message(e)
    return 400, message(e)
