"""What an applied edit script noted about a version it made: its ik and rotate commands' notes
(modb_kernel.edits.apply_with_notes), kept in the version's load_params.edit_script.notes, read
back for the CLI, the REST answer and a job's result."""

from __future__ import annotations

from typing import Any

import psycopg


def version_notes(conn: psycopg.Connection, clip_id: int, version: int) -> list[dict[str, Any]]:
    """The notes of the edit script that made the clip's version (empty when it noted nothing)."""
    row = conn.execute(
        "SELECT load_params->'edit_script'->'notes' FROM modb.clip_versions "
        "WHERE clip_id = %s AND version = %s",
        [clip_id, version],
    ).fetchone()
    return row[0] if row and isinstance(row[0], list) else []


def messages(notes: list[dict[str, Any]]) -> list[str]:
    """The notes that say something went otherwise than asked (an ik target out of reach)."""
    return [n["message"] for n in notes if isinstance(n, dict) and n.get("message")]
