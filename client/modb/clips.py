"""Finding clips by id or name and reading a version back into the shared Motion model."""

from __future__ import annotations

import dataclasses

import numpy as np
import psycopg

from modb.motion import Motion, Skeleton, Source


class ClipNotFound(LookupError):
    pass


def resolve_clip(conn: psycopg.Connection, spec: str) -> int:
    """A clip id from 'id:N', an id, a name, or 'collection/path/name' matching exactly one clip."""
    if spec.startswith("id:") and spec[3:].isdigit():
        if conn.execute("SELECT 1 FROM modb.clips WHERE id = %s", [int(spec[3:])]).fetchone():
            return int(spec[3:])
        raise ClipNotFound(f"no clip with id {spec[3:]}")
    if spec.isdigit():
        by_id = conn.execute("SELECT 1 FROM modb.clips WHERE id = %s", [int(spec)]).fetchone()
        named = conn.execute("SELECT count(*) FROM modb.clips WHERE name = %s", [spec]).fetchone()[
            0
        ]
        if by_id and named:
            raise ClipNotFound(
                f"{spec!r} is both a clip id and a clip name: write id:{spec} for the id, "
                f"or collection/{spec} for the name"
            )
        if by_id:
            return int(spec)
        if not named:
            raise ClipNotFound(f"no clip with id or name {spec}")
    collection, _, name = spec.rpartition("/")
    rows = conn.execute(
        "SELECT c.id, modb.collection_path(c.collection_id) || '/' || c.name FROM modb.clips c "
        "WHERE c.name = %s AND (%s = '' OR modb.collection_path(c.collection_id) = %s) ORDER BY "
        "c.id",
        [name, collection, collection],
    ).fetchall()
    if len(rows) == 1:
        return rows[0][0]
    if not rows:
        raise ClipNotFound(f"no clip named {spec!r} (`modb list` shows what is stored)")
    listing = "\n".join(f"  {clip_id}  {path}" for clip_id, path in rows)
    raise ClipNotFound(
        f"{len(rows)} clips are named {spec!r}; give an id or collection/name:\n{listing}"
    )


def collection_clips(conn: psycopg.Connection, path: str) -> list[int]:
    """The clips (with a version) of the collection at `path` and of those below it."""
    rows = conn.execute(
        "SELECT c.clip_id FROM modb.current_clips c JOIN modb.clips k ON k.id = c.clip_id "
        "WHERE k.collection_id = ANY (modb.collection_subtree(%s)) ORDER BY 1",
        [path],
    ).fetchall()
    return [r[0] for r in rows]


def clips_in(conn: psycopg.Connection, spec: str) -> list[int]:
    """The clips of the collection at path `spec` and those below it, else the one clip it names."""
    return collection_clips(conn, spec) or [resolve_clip(conn, spec)]


def read_motion(conn: psycopg.Connection, clip_id: int, version: int | None = None) -> Motion:
    """The given version of a clip (the newest when None) as a Motion (float64 arrays); for a clip
    cut at an annotated segment (modb.clip_segments), its frames of the source version."""
    (has_segments,) = conn.execute(  # modb 0.14.0 and later
        "SELECT to_regclass('modb.clip_segments') IS NOT NULL"
    ).fetchone()
    segment = (
        has_segments
        and conn.execute(
            "SELECT c.name, s.source_clip, s.source_version, s.first_frame, s.last_frame, "
            "s.annotation "
            "FROM modb.clip_segments s JOIN modb.clips c ON c.id = s.clip_id WHERE s.clip_id = %s",
            [clip_id],
        ).fetchone()
    )
    if segment and version is None:
        name, source_clip, source_version, first, last, annotation = segment
        whole = read_motion(conn, source_clip, source_version)
        cut_from = {"clip_id": source_clip, "version": source_version, "annotation": annotation,
                    "first_frame": first, "last_frame": last}  # fmt: skip
        return dataclasses.replace(
            whole,
            rotations=whole.rotations[first : last + 1],
            translations=whole.translations[first : last + 1],
            name=name,
            meta={**whole.meta, "cut_from": cut_from},
        )
    with conn.cursor(binary=True) as cur:
        row = cur.execute(
            "SELECT c.name, v.version, v.fps, v.rotations, v.translations, v.source_file, "
            "v.source_sha256, "
            "       v.load_params, v.meta, s.name, s.hierarchy, s.joint_map, s.mirror_pairs, "
            "       to_jsonb(s)->'joint_axes' "  # modb 0.15.0 and later; NULL before
            "FROM modb.clips c JOIN modb.clip_versions v ON v.clip_id = c.id "
            "JOIN modb.skeletons s ON s.id = v.skeleton_id "
            "WHERE c.id = %s AND v.version = coalesce(%s, (SELECT max(version) FROM "
            "modb.clip_versions "
            "                                               WHERE clip_id = %s))",
            [clip_id, version, clip_id],
        ).fetchone()
    if row is None:
        which = f"version {version}" if version is not None else "any version"
        raise ClipNotFound(f"clip {clip_id} has no {which}")
    (
        name,
        version,
        fps,
        rotations,
        translations,
        source_file,
        sha,
        load_params,
        meta,
        skeleton_name,
        hierarchy,
        joint_map,
        mirror_pairs,
        joint_axes,
    ) = row
    skeleton = Skeleton.from_row(
        hierarchy, joint_map, mirror_pairs, name=skeleton_name, joint_axes=joint_axes
    )
    n_frames = rotations.shape[0]
    translations = (
        np.zeros((n_frames, 0, 3))
        if translations is None
        else np.asarray(translations, dtype=np.float64)
    )
    return Motion(
        skeleton=skeleton,
        fps=fps,
        rotations=np.asarray(rotations, dtype=np.float64),
        translations=translations,
        name=name,
        source=Source(
            path=source_file or "", sha256=sha or "", units_rule=load_params.get("units_rule", "")
        ),
        meta={"version": version, "load_params": load_params, **meta},
    )
