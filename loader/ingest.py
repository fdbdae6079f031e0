"""Loading motion files into the modb schema: one transaction per file, idempotent re-loads."""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple
from pathlib import Path

import psycopg

from modb.motion import Motion

from .errors import MotionFileError
from .licences import LICENCE_KEYS
from .sources import SourceFile
from .reading import ReadOptions, read_key, read_source
from .sidecars import file_meta
from .skeleton_maps import describe_filled, explain_joint_map


@dataclass
class FileResult:
    path: Path
    status: str  # 'loaded' | 'unchanged' | 'failed'
    clip_id: int | None = None
    version: int | None = None
    frames: int = 0
    seconds_of_motion: float = 0.0
    units_rule: str = ""
    snippets: int = 0
    message: str = ""
    # which standard joints the joint map took from the hierarchy ('' when names gave them all)
    joint_map_note: str = ""


class Stored(NamedTuple):
    clip_id: int
    version: int | None  # None: the same motion is stored already
    snippets: int
    note: str = ""


@dataclass
class PackedBlocks:
    """The snippet blocks of one pose and rate, packed after a load (modb.pack_snippet_blocks)."""

    pose_key: str
    fps: float
    snippets: int
    blocks: int
    seconds: float

    def describe(self) -> str:
        return (
            f"packed the snippet blocks of {self.snippets:,} snippets at {self.fps:g} fps into "
            f"{self.blocks:,} blocks of near ones ({self.seconds:.1f} s): boxes meet fewer"
        )


@dataclass
class LoadSummary:
    results: list[FileResult] = field(default_factory=list)
    elapsed: float = 0.0
    packed: list[PackedBlocks] = field(default_factory=list)

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.results)

    @property
    def frames(self) -> int:
        return sum(r.frames for r in self.results if r.status == "loaded")

    @property
    def failed(self) -> list[FileResult]:
        return [r for r in self.results if r.status == "failed"]

    def describe(self) -> str:
        loaded = self.count("loaded")
        rate = self.frames / self.elapsed if self.elapsed > 0 else 0.0
        motion = sum(r.seconds_of_motion for r in self.results if r.status == "loaded")
        snippets = sum(r.snippets for r in self.results)
        return (
            f"{len(self.results)} files: {loaded} clip versions loaded ({self.frames:,} frames, "
            f"{motion:,.1f} s of motion, {snippets:,} snippets), "
            f"{self.count('unchanged')} unchanged, "
            f"{len(self.failed)} failed; {self.elapsed:.1f} s, {rate:,.0f} frames/s"
        ) + "".join(f"\n{p.describe()}" for p in self.packed)


_UNCHANGED_SQL = """
SELECT v.clip_id, v.version
  FROM modb.clips c
  JOIN LATERAL (SELECT clip_id, version, source_sha256, load_params FROM modb.clip_versions
                 WHERE clip_id = c.id ORDER BY version DESC LIMIT 1) v ON true
 WHERE c.collection_id = modb.find_collection(%(collection)s) AND c.name = %(name)s
   AND v.source_sha256 = %(sha)s AND v.load_params->>'read_key' = %(key)s
"""


def _unchanged(
    conn: psycopg.Connection, source: SourceFile, name: str, sha256: str, key: str
) -> tuple[int, int] | None:
    """(clip, version) when this clip's newest version is from the same bytes read the same way."""
    row = conn.execute(
        _UNCHANGED_SQL, {"collection": source.collection, "name": name, "sha": sha256, "key": key}
    ).fetchone()
    return (row[0], row[1]) if row else None


def _content_key(motion: Motion) -> str:
    """What the stored motion follows from once the file is read.

    The file's bytes, its skeleton file and how they were read.
    """
    src = motion.source
    parts = (
        src.sha256 if src else "",
        str(motion.meta.get("skeleton_sha256", "")),
        repr(motion.skeleton.unit_m),
        repr(motion.fps),
        str(motion.n_frames),
    )
    return hashlib.sha256("|".join(parts).encode()).hexdigest()


class SnippetsError(Exception):
    """The database could not cut a stored clip into snippets: the file fails, none of it stays."""


def build_snippets(conn: psycopg.Connection, clip_id: int, mirrored: bool = False) -> int:
    """Cut the clip's newest version into snippets (and, when asked, its mirror image), inside the
    caller's transaction. A clip that cannot be cut (e.g. its skeleton's joint map is incomplete)
    raises SnippetsError: a clip loaded without its snippets would be lost to the selection."""
    try:
        added = conn.execute("SELECT modb.build_snippets(clip => %s)", [clip_id]).fetchone()[0]
        if mirrored:
            added += conn.execute(
                "SELECT modb.build_snippets(clip => %s, mirrored => true)", [clip_id]
            ).fetchone()[0]
        return added
    except psycopg.OperationalError:
        raise  # the connection, not the clip
    except psycopg.Error as e:
        hint = f" ({e.diag.message_hint})" if e.diag.message_hint else ""
        raise SnippetsError(
            f"its snippets could not be built: {e.diag.message_primary or e}{hint}; nothing of it "
            "was stored (--no-snippets stores the clip alone)"
        ) from e


def store_motion(
    conn: psycopg.Connection,
    motion: Motion,
    collection: str,
    key: str,
    snippets: bool = False,
    mirrored: bool = False,
    meta: dict | None = None,
) -> Stored:
    """Store a parsed clip as a new version in one transaction, with its snippets when asked. Its
    meta: `meta` when given (the files beside it), else the previous version's (its annotations
    only when it has as many frames: they are frame numbers; the note says where they stay)."""
    sk = motion.skeleton
    hierarchy = json.dumps(sk.hierarchy_json())
    src = motion.source
    with conn.transaction():
        (collection_id,) = conn.execute(
            "SELECT modb.ensure_collection(%s)", [collection]
        ).fetchone()
        row = conn.execute(
            "INSERT INTO modb.skeletons (name, hierarchy, joint_map, mirror_pairs) "
            "VALUES (%s, %s::jsonb, %s::jsonb, %s::jsonb) "
            "ON CONFLICT (identity_sha256) DO NOTHING RETURNING id",
            [
                sk.name,
                hierarchy,
                json.dumps(sk.joint_map),
                json.dumps([list(p) for p in sk.mirror_pairs]),
            ],
        ).fetchone()
        # None: the same skeleton is stored already (its joint map may have been edited: keep it;
        # offsets that position channels replace are the first file's, which changes no pose).
        if row is None:
            row = conn.execute(
                "SELECT id FROM modb.skeletons "
                "WHERE identity_sha256 = modb.skeleton_identity(%s::jsonb)",
                [hierarchy],
            ).fetchone()
        skeleton_id = row[0]
        conn.execute(
            "INSERT INTO modb.clips (collection_id, name) VALUES (%s, %s) "
            "ON CONFLICT (collection_id, name) DO NOTHING",
            [collection_id, motion.name],
        )
        (clip_id,) = conn.execute(
            "SELECT id FROM modb.clips WHERE collection_id = %s AND name = %s FOR UPDATE",
            [collection_id, motion.name],
        ).fetchone()
        content = _content_key(motion)
        latest = conn.execute(
            "SELECT load_params->>'content_key', skeleton_id FROM modb.clip_versions "
            "WHERE clip_id = %s ORDER BY version DESC LIMIT 1",
            [clip_id],
        ).fetchone()
        if latest == (content, skeleton_id):  # e.g. --units auto, then cm: the same motion
            return Stored(clip_id, None, 0)
        meta, note = _new_version_meta(conn, clip_id, motion.n_frames, meta)
        load_params = {
            "read_key": key,
            "content_key": content,
            "unit_m": sk.unit_m,
            "units_rule": src.units_rule if src else "",
            **motion.meta,
        }
        translations = motion.translations if motion.translations.shape[1] else None
        (version,) = conn.execute(
            "INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, "
            "translations, source_file, source_sha256, load_params, meta) "
            "VALUES (%s, %s, %s, %s, %b, %b, %s, %s, %s::jsonb, %s::jsonb) RETURNING version",
            [
                clip_id,
                skeleton_id,
                motion.fps,
                motion.n_frames,
                motion.rotations,
                translations,
                src.path if src else None,
                src.sha256 if src else None,
                json.dumps(load_params),
                json.dumps(meta),
            ],
        ).fetchone()
        added = build_snippets(conn, clip_id, mirrored) if snippets else 0
        return Stored(clip_id, version, added, note)


def _new_version_meta(
    conn: psycopg.Connection, clip_id: int, n_frames: int, given: dict | None
) -> tuple[dict, str]:
    """A new version's meta and what to say about the previous version's (see store_motion); a
    licence the new file states or finds replaces the previous version's, which stays otherwise."""
    given = dict(given or {})
    terms = {k: given.pop(k) for k in LICENCE_KEYS if k in given}
    previous = conn.execute(
        "SELECT version, n_frames, meta FROM modb.clip_versions WHERE clip_id = %s "
        "ORDER BY version DESC LIMIT 1",
        [clip_id],
    ).fetchone()
    meta, note = _carried_meta(previous, n_frames, given)
    if not terms and previous:  # the previous version's, even where a sidecar gives the rest anew
        terms = {k: previous[2][k] for k in LICENCE_KEYS if k in (previous[2] or {})}
    return {**{k: v for k, v in meta.items() if k not in LICENCE_KEYS}, **terms}, note


def _carried_meta(previous: tuple | None, n_frames: int, given: dict) -> tuple[dict, str]:
    """What of the previous version's (version, n_frames, meta) the new one keeps, and the note."""
    if given:
        return given, ""
    if previous is None or not previous[2]:
        return {}, ""
    version, frames, meta = previous
    if frames == n_frames:
        return meta, f"annotations and tags carried over from version {version}"
    kept = {k: v for k, v in meta.items() if k != "annotations"}  # tags are not frame numbers
    if "annotations" not in meta:
        return kept, ""
    return kept, (
        f"version {version}'s annotations stay with it: it has {frames} frames, this one {n_frames}"
    )


def load_files(
    conn: psycopg.Connection,
    sources: list[SourceFile],
    options: ReadOptions,
    keep_going: bool,
    progress: Callable[[FileResult], None] | None = None,
    snippets: bool = True,
    mirrored: bool = False,
) -> LoadSummary:
    """Load each file in its own transaction. Stops at the first bad file unless keep_going; with
    it, every file is tried and reported, whatever goes wrong with one (once the connection is lost,
    each remaining file says so)."""
    summary = LoadSummary()
    started = time.perf_counter()
    noted: set[str] = set()
    for source in sources:
        if conn.closed:
            result = FileResult(
                source.path, "failed", message=f"{source.path}: not loaded: the connection was lost"
            )
        else:
            result = _load_one(conn, source, options, snippets, mirrored)
            said = result.joint_map_note.partition(": ")[2]  # once per kind of skeleton
            if said in noted:
                result.joint_map_note = ""
            noted.add(said)
        summary.results.append(result)
        if progress:
            progress(result)
        if result.status == "failed" and not keep_going:
            break
    if any(r.snippets for r in summary.results) and not conn.closed:
        _analyze(conn)
        summary.packed = pack_blocks(conn)
    summary.elapsed = time.perf_counter() - started
    return summary


# A pose whose snippets are at least this share in blocks of consecutive ones (as loads add them) is
# packed after a load: a first load, or one that grew it by a fifth, not every small one.
PACK_SHARE = 0.2


def pack_blocks(conn: psycopg.Connection, min_share: float = PACK_SHARE) -> list[PackedBlocks]:
    """Packs the snippet blocks of the poses that loads have grown (its own transaction; about 25 s
    a million snippets, docs/performance.md). What it leaves unpacked is correct, only slower."""
    with conn.transaction():
        if conn.execute(
            "SELECT to_regprocedure('modb.pack_snippet_blocks(float8)') IS NULL"
        ).fetchone()[0]:
            return []  # an extension older than 0.11.0, not updated yet
        rows = conn.execute(
            "SELECT pose_key, fps, snippets, blocks, seconds FROM modb.pack_snippet_blocks(%s)",
            [min_share],
        ).fetchall()
    return [PackedBlocks(*row) for row in rows]


def _analyze(conn: psycopg.Connection) -> None:
    """Fresh statistics once per load, so the planner sees the new snippets at once (autovacuum gets
    there later). Only the tables' owner may; a loader role leaves it to autovacuum."""
    (owner,) = conn.execute(
        "SELECT pg_has_role(relowner, 'USAGE') FROM pg_class WHERE oid = 'modb.snippets'::regclass"
    ).fetchone()
    if owner:
        conn.execute("ANALYZE modb.snippets, modb.terminators")


def _refused(source: SourceFile, e: psycopg.Error) -> str:
    diag = e.diag
    parts = (diag.message_primary, diag.message_detail, diag.message_hint)
    detail = "; ".join(x for x in parts if x)
    return f"{source.path}: the database refused the clip: {detail or e}"


def _load_one(
    conn: psycopg.Connection,
    source: SourceFile,
    options: ReadOptions,
    snippets: bool,
    mirrored: bool,
) -> FileResult:
    name = source.path.stem
    try:
        raw = source.folder.read(source.path)  # once: hashed here, parsed below
        sha = hashlib.sha256(raw).hexdigest()
        key = read_key(source, options)
        hit = _unchanged(conn, source, name, sha, key)
        if hit:  # cut it now if an earlier load skipped the snippets
            with conn.transaction():
                added = build_snippets(conn, hit[0], mirrored) if snippets else 0
            return FileResult(
                source.path, "unchanged", clip_id=hit[0], version=hit[1], snippets=added
            )
        motion = read_source(source, options, raw)
        del raw  # a large file's bytes need not outlive its parse
        meta = file_meta(
            source.path, motion.n_frames, source.folder, options.labels, options.licence
        )
        clip_id, version, added, note = store_motion(
            conn, motion, source.collection, key, snippets, mirrored, meta
        )
    except MotionFileError as e:
        return FileResult(source.path, "failed", message=str(e))
    except SnippetsError as e:
        return FileResult(source.path, "failed", message=f"{source.path}: {e}")
    except OSError as e:
        return FileResult(
            source.path, "failed", message=f"{source.path}: cannot read: {e.strerror or e}"
        )
    except psycopg.OperationalError as e:
        if conn.closed:
            return FileResult(
                source.path,
                "failed",
                message=f"{source.path}: not loaded: the connection was lost ({e})",
            )
        return FileResult(source.path, "failed", message=_refused(source, e))
    except psycopg.Error as e:
        return FileResult(source.path, "failed", message=_refused(source, e))
    except Exception as e:  # a bug: this file fails with what went wrong, the batch goes on
        return FileResult(
            source.path,
            "failed",
            message=f"{source.path}: not loaded: {type(e).__name__}: {e} (a modb bug: please "
            "report it with this file)",
        )
    if version is None:
        return FileResult(source.path, "unchanged", clip_id=clip_id)
    return FileResult(
        source.path,
        "loaded",
        clip_id=clip_id,
        version=version,
        frames=motion.n_frames,
        seconds_of_motion=motion.n_frames / motion.fps,
        units_rule=motion.source.units_rule if motion.source else "",
        snippets=added,
        message=note,
        joint_map_note=describe_filled(
            motion.skeleton.name,
            motion.skeleton.joint_map,
            explain_joint_map(motion.skeleton.names, motion.skeleton.parents)[1],
        ),
    )
