"""The read-only JSON views of the motion database (the DFKI data server's browsing role).

Each function takes a connection and validated arguments and returns what the endpoint sends;
unknown ids raise NotFound and bad arguments BadRequest (the app's 404 and 400, with the message).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import psycopg
from modb_kernel.joints import STANDARD_JOINTS

from modb.demo import MODEL_GRAPH
from modb.motion import Motion, Skeleton

MAX_FRAMES = 20_000  # per request: a clip longer than this is fetched in pages (start, count)


class NotFound(LookupError):
    pass


class BadRequest(ValueError):
    pass


def _rows(
    conn: psycopg.Connection, query: str, params: list[Any] | None = None
) -> list[dict[str, Any]]:
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        return cur.execute(query, params or []).fetchall()


def _one(conn: psycopg.Connection, what: str, query: str, ident: int) -> dict[str, Any]:
    rows = _rows(conn, query, [ident])
    if not rows:
        raise NotFound(f"no {what} with id {ident}")
    return rows[0]


def collections(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """Every collection with its path and how many clips it holds directly."""
    return _rows(
        conn,
        "SELECT c.id, c.parent_id, c.name, modb.collection_path(c.id) AS path, "
        "       (SELECT count(*) FROM modb.clips k WHERE k.collection_id = c.id) AS clips "
        "  FROM modb.collections c ORDER BY path",
    )


_CLIP_LIST = """
SELECT c.id, c.name, c.collection_id, modb.collection_path(c.collection_id) AS collection,
       v.version, v.n_frames, v.fps, v.skeleton_id
  FROM modb.clips c
  JOIN LATERAL (SELECT * FROM modb.clip_versions v WHERE v.clip_id = c.id
                 ORDER BY v.version DESC LIMIT 1) v ON true
"""


def clips(
    conn: psycopg.Connection,
    collection_id: int | None,
    tag: str | None = None,
    annotation: str | None = None,
) -> list[dict[str, Any]]:
    """The clips of one collection (all when None), newest versions; with `tag`, those whose newest
    version has it, with `annotation`, those whose newest version has a segment so named."""
    if collection_id is not None:
        _one(conn, "collection", "SELECT id FROM modb.collections WHERE id = %s", collection_id)
    return _rows(
        conn,
        _CLIP_LIST + " WHERE (%(c)s::bigint IS NULL OR c.collection_id = %(c)s)"
        "   AND (%(tag)s::text IS NULL OR v.meta->'tags' ? %(tag)s)"
        "   AND (%(name)s::text IS NULL OR v.meta->'annotations' @> jsonb_build_array("
        "        jsonb_build_object('name', %(name)s::text)))"
        " ORDER BY c.name, c.id",
        {"c": collection_id, "tag": tag, "name": annotation},
    )


def clip(conn: psycopg.Connection, clip_id: int) -> dict[str, Any]:
    """One clip: its newest version's shape, every version, and its annotations."""
    out = _one(conn, "clip", _CLIP_LIST + " WHERE c.id = %s", clip_id)
    out["versions"] = _rows(
        conn,
        "SELECT version, n_frames, fps, skeleton_id, source_file, created_at::text, "
        "       meta FROM modb.clip_versions WHERE clip_id = %s ORDER BY version",
        [clip_id],
    )
    return out


# The version asked for (the newest when NULL) and its skeleton, without its frames.
_VERSION = """
SELECT v.version, v.fps, v.n_frames, s.name, s.hierarchy, s.joint_map, s.mirror_pairs
  FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
 WHERE v.clip_id = %s
   AND v.version = coalesce(%s, (SELECT max(version) FROM modb.clip_versions WHERE clip_id = %s))
"""
# Frames first..last (1-based, inclusive) of every joint: PostgreSQL slices the arrays, so only
# the asked frames leave the database, however long the clip.
_SLICE = """
SELECT v.rotations[%s:%s][:][:], v.translations[%s:%s][:][:]
  FROM modb.clip_versions v WHERE v.clip_id = %s AND v.version = %s
"""


def check_page(start: int, count: int | None) -> None:
    """BadRequest unless start and count (None: as many as one answer gives) name a page."""
    if start < 0:
        raise BadRequest(f"start must be 0 or more, got {start}")
    if count is not None and not 1 <= count <= MAX_FRAMES:
        raise BadRequest(f"count must be 1-{MAX_FRAMES}, got {count}")


def frames(
    conn: psycopg.Connection, clip_id: int, version: int | None, start: int, count: int | None
) -> dict[str, Any]:
    """Frames start..start+count-1 of a clip version: local rotations (w, x, y, z per joint,
    skeleton order), the translations of the joints that have position channels, and every joint's
    world position (metres), computed here by the shared forward kinematics. Only those frames are
    read from the database."""
    check_page(start, count)
    _one(conn, "clip", "SELECT id FROM modb.clips WHERE id = %s", clip_id)
    row = conn.execute(_VERSION, [clip_id, version, clip_id]).fetchone()
    if row is None:
        which = f"version {version}" if version is not None else "any version"
        raise NotFound(f"clip {clip_id} has no {which}")
    version, fps, n_frames, skeleton_name, hierarchy, joint_map, mirror_pairs = row
    if start >= n_frames:
        raise BadRequest(f"start {start} is past the clip's last frame ({n_frames - 1})")
    stop = min(n_frames, start + (count or MAX_FRAMES))
    with conn.cursor(binary=True) as cur:
        rotations, translations = cur.execute(
            _SLICE, [start + 1, stop, start + 1, stop, clip_id, version]
        ).fetchone()
    skeleton = Skeleton.from_row(hierarchy, joint_map, mirror_pairs, name=skeleton_name)
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = (
        np.zeros((stop - start, 0, 3))
        if translations is None
        else np.asarray(translations, dtype=np.float64)
    )
    if rotations.shape[0] != stop - start or translations.shape[0] != stop - start:
        raise RuntimeError(
            f"clip {clip_id} version {version}: asked for frames {start}-{stop - 1}, "
            f"the database gave {rotations.shape[0]}"
        )
    positions = Motion(skeleton, fps, rotations, translations, name="").world_positions()
    return {
        "clip_id": clip_id,
        "version": version,
        "fps": fps,
        "n_frames": n_frames,
        "start": start,
        "count": stop - start,
        "joints": skeleton.names,
        "translated": skeleton.translated,
        "rotations": np.round(rotations, 7).tolist(),
        "translations": np.round(translations, 6).tolist(),
        "positions": np.round(positions, 6).tolist(),
    }


def skeletons(conn: psycopg.Connection) -> list[dict[str, Any]]:
    return _rows(
        conn,
        "SELECT s.id, s.name, s.hierarchy->>'format' AS format, "
        "       jsonb_array_length(s.hierarchy->'joints') AS joints, "
        "       (SELECT count(*) FROM modb.clip_versions v WHERE v.skeleton_id = s.id) "
        "         AS clip_versions "
        "  FROM modb.skeletons s ORDER BY s.id",
    )


def skeleton(conn: psycopg.Connection, skeleton_id: int) -> dict[str, Any]:
    """The hierarchy (offsets in metres, channels, rest positions), joint map and mirror pairs."""
    return _one(
        conn,
        "skeleton",
        "SELECT id, name, hierarchy, joint_map, mirror_pairs, meta, "
        "       coalesce(to_jsonb(s)->'joint_axes', '{}') AS joint_axes "  # modb 0.15.0 on
        "  FROM modb.skeletons s WHERE id = %s",
        skeleton_id,
    )


def _named_table(table: str) -> tuple[str, str]:
    # a model's version (0.22.0 on), its meta without the acceleration tree (megabytes)
    version = ", (to_jsonb(t)->>'version')::int AS version" if table == "models" else ""
    listing = (
        f"SELECT id, name, kind, skeleton_id, meta - 'tree' AS meta, created_at::text{version} "
        f"FROM modb.{table} t ORDER BY name, kind{version and ', version'}"
    )
    one = (
        f"SELECT id, name, kind, skeleton_id, data, meta, created_at::text FROM modb.{table} "
        "WHERE id = %s"
    )
    return listing, one


def models(conn: psycopg.Connection) -> list[dict[str, Any]]:
    return _rows(conn, _named_table("models")[0])


def model(conn: psycopg.Connection, model_id: int) -> dict[str, Any]:
    return _one(conn, "model", _named_table("models")[1], model_id)


def graphs(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """Motion and transition graphs; transition graphs with how many snippets they keep."""
    rows = _rows(conn, _named_table("graphs")[0])
    kept = dict(
        conn.execute(
            "SELECT graph_id, count(*) FROM modb.graph_snippets GROUP BY graph_id"
        ).fetchall()
    )
    for r in rows:
        r["kept_snippets"] = kept.get(r["id"], 0)
    return rows


def graph(conn: psycopg.Connection, graph_id: int) -> dict[str, Any]:
    out = _one(conn, "graph", _named_table("graphs")[1], graph_id)
    out["kept_snippets"] = conn.execute(
        "SELECT count(*) FROM modb.graph_snippets WHERE graph_id = %s", [graph_id]
    ).fetchone()[0]
    return out


def edit_scripts(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """The stored edit scripts (modb.apply_edit_script runs one)."""
    return _rows(
        conn,
        "SELECT name, commands, comment, created_at::text, created_by FROM modb.edit_scripts "
        "ORDER BY name",
    )


def profiles(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """select_next_snippet's match profiles and settings: the avatar panel's starting values."""
    return _rows(
        conn, "SELECT name, settings, comment, shipped FROM modb.match_profiles ORDER BY name"
    )


# the graphs of models as the avatar page offers them: `modb demo`'s first, then by name
MODEL_GRAPHS = "SELECT name FROM modb.graphs WHERE kind = 'models' ORDER BY name <> %s, name"


def avatar_choices(conn: psycopg.Connection) -> dict[str, Any]:
    """The avatar panel's choices: profiles, transition graphs newest first, collections, joints;
    and the graphs of models it can walk on instead, by name, `modb demo`'s first (named in
    demo_model_graph when the database has it)."""
    graphs = [
        r[0]
        for r in conn.execute(
            "SELECT name FROM modb.graphs WHERE kind = 'transitions' "
            "ORDER BY created_at DESC, id DESC"
        )
    ]
    models = conn.execute(MODEL_GRAPHS, [MODEL_GRAPH])
    model_graphs = [r[0] for r in models]
    return {
        "profiles": profiles(conn),
        "graphs": graphs,
        "model_graphs": model_graphs,
        "demo_model_graph": MODEL_GRAPH if MODEL_GRAPH in model_graphs else None,
        "collections": [c["path"] for c in collections(conn)],
        "joints": list(STANDARD_JOINTS),
    }


def processed_data(
    conn: psycopg.Connection, collection: str | None, primitive: str | None
) -> list[dict[str, Any]]:
    """Processed-data rows without their frames (modb.processed_data_status: stale says why a row
    is stale), of a collection and primitive when given; none before 0.21.0."""
    if not conn.execute("SELECT to_regclass('modb.processed_data_status')").fetchone()[0]:
        return []
    rows = conn.execute(
        "SELECT to_jsonb(s) FROM modb.processed_data_status s "
        "WHERE (%(c)s::text IS NULL OR collection = %(c)s) "
        "AND (%(p)s::text IS NULL OR primitive = %(p)s) ORDER BY collection, primitive, id",
        {"c": collection, "p": primitive},
    )
    return [r for (r,) in rows]


def processed_row(conn: psycopg.Connection, row_id: int) -> dict[str, Any]:
    """One processed-data row whole: its aligned frames, time function, sections and settings."""
    row = conn.execute(
        "SELECT to_jsonb(s) || to_jsonb(p) FROM modb.processed_data p "
        "JOIN modb.processed_data_status s USING (id) WHERE p.id = %s",
        [row_id],
    ).fetchone()
    if row is None:
        raise NotFound(f"no processed-data row with id {row_id}")
    return row[0]
