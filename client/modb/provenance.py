"""Where a clip's motion was captured and under which terms: a retargeted clip's origin is the clip
it was made from (load_params.retargeted_from, followed back to a loaded file), its licence the one
the loader recorded there (loader/licences.py). Exports of a synthesized strip name every source
they draw from this way, and the avatar shows each chosen snippet's."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass

import psycopg

# Each clip version (one that exists), followed back to where its motion was loaded: through its
# retargeted_from link (another clip's version) or the version an edit script started from (the same
# clip's); the deepest row per version is its origin.
ORIGINS = """
WITH RECURSIVE chain(clip_id, version, at_clip, at_version, depth) AS (
    SELECT k.clip_id, k.version, k.clip_id, k.version, 0
      FROM unnest(%s::bigint[], %s::int[]) AS k(clip_id, version)
      JOIN modb.clip_versions v ON v.clip_id = k.clip_id AND v.version = k.version
    UNION ALL
    SELECT chain.clip_id, chain.version,
           coalesce((v.load_params->'retargeted_from'->>'clip_id')::bigint, chain.at_clip),
           coalesce((v.load_params->'retargeted_from'->>'version')::int,
                    (v.load_params->'edit_script'->>'from_version')::int),
           chain.depth + 1
      FROM chain
      JOIN modb.clip_versions v ON v.clip_id = chain.at_clip AND v.version = chain.at_version
     WHERE (jsonb_typeof(v.load_params->'retargeted_from') = 'object'
            OR jsonb_typeof(v.load_params->'edit_script'->'from_version') = 'number')
       AND chain.depth < 64
)
SELECT DISTINCT ON (chain.clip_id, chain.version) chain.clip_id, chain.version,
       modb.collection_path(c.collection_id), c.name, v.meta->>'licence'
  FROM chain
  JOIN modb.clips c ON c.id = chain.at_clip
  LEFT JOIN modb.clip_versions v ON v.clip_id = chain.at_clip AND v.version = chain.at_version
 ORDER BY chain.clip_id, chain.version, chain.depth DESC
"""
Version = tuple[int, int]  # (clip id, version)
UNKNOWN_LICENCE = "licence not recorded"  # `modb load --licence` states it


@dataclass(frozen=True)
class Origin:
    collection: str  # the collection the motion was loaded into
    clip: str
    licence: str | None


@dataclass(frozen=True)
class SourceShare:
    """One source of a strip: a collection motion was loaded into, its licence, and how many of
    the strip's snippets came from it."""

    source: str
    licence: str
    snippets: int


def origins(conn: psycopg.Connection, versions: Iterable[Version]) -> dict[Version, Origin]:
    """Each clip version's origin (a version that does not exist has none)."""
    keys = sorted(set(versions))
    rows = conn.execute(ORIGINS, [[k[0] for k in keys], [k[1] for k in keys]])
    return {(row[0], row[1]): Origin(*row[2:]) for row in rows}


@dataclass(frozen=True)
class StripSources:
    shares: list[SourceShare]  # most used first
    crossings: int  # seams from one source's snippet to another's

    def summary(self) -> str:
        total = sum(s.snippets for s in self.shares) or 1
        return (
            "sources: "
            + "; ".join(f"{s.source} {s.snippets / total:.0%} ({s.licence})" for s in self.shares)
            + f"; {self.crossings} seam{'' if self.crossings == 1 else 's'} between sources"
        )


def strip_sources(conn: psycopg.Connection, versions: Sequence[Version]) -> StripSources:
    """The sources of a strip whose snippets came from these clip versions (one per snippet, in
    order)."""
    return sources_among(origins(conn, versions), versions)


def sources_among(
    found: Mapping[Version, Origin | None], versions: Sequence[Version]
) -> StripSources:
    """strip_sources with the origins already known (a version without one is left out)."""
    keys = [
        (o.collection, o.licence or UNKNOWN_LICENCE) if (o := found.get(v)) else None
        for v in versions
    ]
    counts = Counter(k for k in keys if k is not None)
    return StripSources(
        [SourceShare(s, licence, n) for (s, licence), n in counts.most_common()],
        sum(1 for a, b in zip(keys, keys[1:], strict=False) if a != b),
    )


def as_meta(sources: StripSources) -> list[dict]:
    """As a Motion's meta["sources"] holds them: what exports write (BVH beside it, glTF inside)."""
    return [asdict(s) for s in sources.shares]


def credits(sources: Sequence[dict]) -> str:
    """One line naming every source of meta["sources"] and its terms (glTF's asset.copyright)."""
    return "; ".join(f"{s['source']}: {s['licence']}" for s in sources)
