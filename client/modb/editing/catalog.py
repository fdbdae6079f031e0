"""Editing the catalogue: collections (create, rename, move, delete), clips and their versions
(delete one, make an older one current again), a skeleton's joint map and mirror pairs, and clips
cut at annotated segments. The SQL functions of 55_catalogue_edits.sql and 78_annotations.sql do the
work; this module adds what a caller needs around them: the snippets cut again when the current
version or the maps change, in the caller's transaction. Shared by the CLI and REST interface."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg import sql
from psycopg.types.json import Jsonb

from modb.loader.ingest import build_snippets

from .meta import entity_tag


@dataclass(frozen=True)
class Recut:
    """What a change of the current version left: the version now current and its snippets."""

    clip_id: int
    version: int
    snippets: int


def _mirrored(conn: psycopg.Connection, clip_id: int) -> bool:
    """Whether the clip was cut mirrored too (kept when it is cut again)."""
    return bool(
        conn.execute(
            "SELECT EXISTS (SELECT FROM modb.snippet_sources WHERE clip_id = %s AND mirrored)",
            [clip_id],
        ).fetchone()[0]
    )


def _snippets(conn: psycopg.Connection, clip_id: int) -> int:
    return conn.execute(
        "SELECT count(*) FROM modb.snippets WHERE clip_id = %s", [clip_id]
    ).fetchone()[0]


def find_collection(conn: psycopg.Connection, path: str) -> int | None:
    return conn.execute("SELECT modb.find_collection(%s)", [path]).fetchone()[0]


def create_collection(conn: psycopg.Connection, path: str) -> tuple[int, str]:
    (found,) = conn.execute("SELECT modb.ensure_collection(%s)", [path]).fetchone()
    return found, conn.execute("SELECT modb.collection_path(%s)", [found]).fetchone()[0]


def rename_collection(conn: psycopg.Connection, path: str, new_name: str) -> str:
    return conn.execute("SELECT modb.rename_collection(%s, %s)", [path, new_name]).fetchone()[0]


def move_collection(conn: psycopg.Connection, path: str, new_parent: str | None) -> str:
    return conn.execute("SELECT modb.move_collection(%s, %s)", [path, new_parent]).fetchone()[0]


def delete_collection(conn: psycopg.Connection, path: str, with_clips: bool = False) -> int:
    """Deletes the collection and those below it; returns how many clips went with them."""
    return conn.execute("SELECT modb.delete_collection(%s, %s)", [path, with_clips]).fetchone()[0]


def delete_clip(conn: psycopg.Connection, clip_id: int) -> int:
    """Deletes the clip, its versions and snippets; returns how many versions went."""
    return conn.execute("SELECT modb.delete_clip(%s)", [clip_id]).fetchone()[0]


def _then_cut(conn: psycopg.Connection, clip_id: int, version: int, function: str) -> Recut:
    """Calls modb.FUNCTION(clip, version), which returns the version now current, and cuts that
    version into snippets as the clip was cut (mirrored too, when it was)."""
    mirrored = _mirrored(conn, clip_id)
    (current,) = conn.execute(
        sql.SQL("SELECT {}(%s, %s)").format(sql.Identifier("modb", function)), [clip_id, version]
    ).fetchone()
    build_snippets(conn, clip_id, mirrored)
    return Recut(clip_id, current, _snippets(conn, clip_id))


def delete_version(conn: psycopg.Connection, clip_id: int, version: int) -> Recut:
    """Deletes one version; when it was the current one, the one before it is cut into snippets."""
    return _then_cut(conn, clip_id, version, "delete_clip_version")


def restore_version(conn: psycopg.Connection, clip_id: int, version: int) -> Recut:
    """Makes an older version current again (as a new version with its motion and meta), cut."""
    return _then_cut(conn, clip_id, version, "restore_clip_version")


class SkeletonNotFound(LookupError):
    pass


class StaleMaps(Exception):
    def __init__(self, current: SkeletonMaps) -> None:
        super().__init__(
            f"skeleton {current.skeleton_id}: its joint map or mirror pairs changed since they "
            f"were read (now {current.etag}); read them again and re-apply the change"
        )
        self.current = current


@dataclass(frozen=True)
class SkeletonMaps:
    skeleton_id: int
    joint_map: dict[str, str]
    mirror_pairs: list[list[str]]
    joint_axes: dict[str, Any] | None  # None: an extension before 0.15.0

    @property
    def document(self) -> dict[str, Any]:
        out = {"joint_map": self.joint_map, "mirror_pairs": self.mirror_pairs}
        return out if self.joint_axes is None else {**out, "joint_axes": self.joint_axes}

    @property
    def etag(self) -> str:
        return entity_tag(self.document)


def read_maps(conn: psycopg.Connection, skeleton_id: int, lock: bool = False) -> SkeletonMaps:
    row = conn.execute(
        "SELECT id, joint_map, mirror_pairs, to_jsonb(s)->'joint_axes' FROM modb.skeletons s "
        "WHERE id = %s" + (" FOR NO KEY UPDATE" if lock else ""),
        [skeleton_id],
    ).fetchone()
    if row is None:
        raise SkeletonNotFound(f"no skeleton {skeleton_id}")
    return SkeletonMaps(*row)


def write_maps(
    conn: psycopg.Connection,
    skeleton_id: int,
    joint_map: dict[str, str],
    mirror_pairs: list[list[str]],
    if_match: str | None,
    joint_axes: dict[str, Any] | None = None,
) -> tuple[SkeletonMaps, list[Recut]]:
    """Replaces the skeleton's joint map and mirror pairs (and joint axes, when given) when their
    entity tag is still `if_match` (None: whatever they are; the table's checks refuse unknown
    joints) and, when the map or pairs changed, cuts every clip whose current version uses the
    skeleton again: its snippets' features come from them."""
    with conn.transaction():
        current = read_maps(conn, skeleton_id, lock=True)
        if if_match is not None and if_match != current.etag:
            raise StaleMaps(current)
        conn.execute(
            "UPDATE modb.skeletons SET joint_map = %s, mirror_pairs = %s WHERE id = %s",
            [Jsonb(joint_map), Jsonb(mirror_pairs), skeleton_id],
        )
        if joint_axes is not None:
            conn.execute(
                "UPDATE modb.skeletons SET joint_axes = %s WHERE id = %s",
                [Jsonb(joint_axes), skeleton_id],
            )
        if (joint_map, mirror_pairs) == (current.joint_map, current.mirror_pairs):
            return read_maps(conn, skeleton_id), []
        cut = conn.execute(
            "SELECT ss.clip_id, bool_or(ss.mirrored) "
            "FROM modb.snippet_sources ss JOIN modb.clip_versions v USING (clip_id, version) "
            "WHERE v.skeleton_id = %s GROUP BY ss.clip_id ORDER BY 1",
            [skeleton_id],
        ).fetchall()
        recut = []
        for clip_id, mirrored in cut:
            conn.execute("DELETE FROM modb.snippet_sources WHERE clip_id = %s", [clip_id])
            build_snippets(conn, clip_id, mirrored)
            (version,) = conn.execute(
                "SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s", [clip_id]
            ).fetchone()
            recut.append(Recut(clip_id, version, _snippets(conn, clip_id)))
        return read_maps(conn, skeleton_id), recut


@dataclass(frozen=True)
class Segment:
    clip_id: int
    name: str
    annotation: str
    first_frame: int
    last_frame: int
    created: bool


def split_by_annotation(
    conn: psycopg.Connection,
    clip_id: int,
    annotation: str | None = None,
    collection: str | None = None,
) -> list[Segment]:
    """A clip per annotated segment of the clip's current version, referring to its frames."""
    rows = conn.execute(
        "SELECT * FROM modb.split_by_annotation(%s, %s, %s)", [clip_id, annotation, collection]
    ).fetchall()
    return [Segment(*row) for row in rows]
