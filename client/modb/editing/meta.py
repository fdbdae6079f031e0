"""A clip version's meta, read with an entity tag and written only over the meta that tag names
(optimistic concurrency: of two editors who read the same meta, the second to save is refused
instead of silently undoing the first's work)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg.types.json import Jsonb

from modb.loader.annotations import AnnotationError, checked, checked_tags

MAX_META_BYTES = 1 << 20  # a version's meta as JSON: annotations and tags, not data


def entity_tag(document: Any) -> str:
    """A strong entity tag of a JSON document's content (jsonb keeps no key order or spacing)."""
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return '"' + hashlib.sha256(text.encode()).hexdigest()[:32] + '"'


class MetaNotFound(LookupError):
    pass


class StaleMeta(Exception):
    """The meta changed since the caller read it."""

    def __init__(self, current: VersionMeta) -> None:
        super().__init__(
            f"clip {current.clip_id} version {current.version}: its meta changed since it was read "
            f"(now {current.etag}); read it again and re-apply the change"
        )
        self.current = current


@dataclass(frozen=True)
class VersionMeta:
    clip_id: int
    version: int
    n_frames: int
    meta: dict[str, Any]

    @property
    def etag(self) -> str:
        return entity_tag(self.meta)


_READ = (
    "SELECT v.clip_id, v.version, v.n_frames, v.meta FROM modb.clip_versions v "
    "WHERE v.clip_id = %(clip)s AND v.version = coalesce(%(version)s, "
    "(SELECT max(version) FROM modb.clip_versions WHERE clip_id = %(clip)s))"
)


def read_meta(conn: psycopg.Connection, clip_id: int, version: int | None = None) -> VersionMeta:
    """The meta of a clip's version (the newest when None)."""
    row = conn.execute(_READ, {"clip": clip_id, "version": version}).fetchone()
    if row is None:
        raise MetaNotFound(
            f"no clip {clip_id}" + (f" version {version}" if version is not None else "")
        )
    return VersionMeta(*row)


def write_meta(
    conn: psycopg.Connection,
    clip_id: int,
    version: int,
    meta: dict[str, Any],
    if_match: str | None,
    also: Callable[[psycopg.Connection, VersionMeta], None] | None = None,
) -> VersionMeta:
    """Replaces the version's meta when its entity tag is still `if_match` (None: whatever it is),
    checking the annotations first; `also` runs in the same transaction (the audit record)."""
    if not isinstance(meta, dict):
        raise AnnotationError("meta is a JSON object")
    if len(json.dumps(meta)) > MAX_META_BYTES:
        raise AnnotationError(f"meta is larger than {MAX_META_BYTES // 1024} KiB")
    with conn.transaction():
        row = conn.execute(_READ + " FOR UPDATE", {"clip": clip_id, "version": version}).fetchone()
        if row is None:
            raise MetaNotFound(f"no clip {clip_id} version {version}")
        current = VersionMeta(*row)
        if if_match is not None and if_match != current.etag:
            raise StaleMeta(current)
        if "annotations" in meta:
            checked(meta["annotations"], current.n_frames)
        if "tags" in meta:
            checked_tags(meta["tags"])
        (stored,) = conn.execute(
            "UPDATE modb.clip_versions SET meta = %s WHERE clip_id = %s AND version = %s "
            "RETURNING meta",
            [Jsonb(meta), clip_id, version],
        ).fetchone()
        written = VersionMeta(clip_id, version, current.n_frames, stored)
        if also:
            also(conn, written)
    return written
