"""Files the web view offers: a clip as BVH or glTF, and a skeleton's character (glTF, at rest) that
the pages pose as a skinned mesh."""

from __future__ import annotations

import io
import re

import psycopg
from starlette.responses import Response

from modb.bvh_export import write_bvh
from modb.clips import ClipNotFound, read_motion
from modb.gltf_export import gltf_bytes, rest_motion
from modb.motion import Motion, Skeleton

from .api import BadRequest, NotFound

# format: (media type, file name extension)
FORMATS = {
    "bvh": ("text/plain; charset=utf-8", "bvh"),
    "glb": ("model/gltf-binary", "glb"),
    "gltf": ("model/gltf+json", "gltf"),
}


def motion_bytes(motion: Motion, fmt: str) -> bytes:
    if fmt not in FORMATS:
        raise BadRequest(f"format must be one of {', '.join(FORMATS)}, got {fmt!r:.50}")
    if fmt == "bvh":
        text = io.StringIO()
        write_bvh(motion, text)
        return text.getvalue().encode("utf-8")
    return gltf_bytes(motion, binary=fmt == "glb")


def file_response(data: bytes, name: str, fmt: str) -> Response:
    # a name that is safe in a header and on any file system
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "motion"
    media, extension = FORMATS[fmt]
    return Response(
        data,
        media_type=media,
        headers={"Content-Disposition": f'attachment; filename="{safe[:100]}.{extension}"'},
    )


def clip_file(conn: psycopg.Connection, clip_id: int, version: int | None, fmt: str) -> Response:
    """A clip version as stored (the source's own layout), as a file to download."""
    if fmt not in FORMATS:
        raise BadRequest(f"format must be one of {', '.join(FORMATS)}, got {fmt!r:.50}")
    try:
        motion = read_motion(conn, clip_id, version)
    except ClipNotFound as e:
        raise NotFound(str(e)) from None
    name = f"{motion.name}_v{motion.meta['version']}"
    return file_response(motion_bytes(motion, fmt), name, fmt)


def skeleton_character(conn: psycopg.Connection, skeleton_id: int) -> Response:
    """The skeleton's character at rest as .glb: the mesh the pages skin and pose."""
    row = conn.execute(
        "SELECT name, hierarchy, joint_map, mirror_pairs FROM modb.skeletons WHERE id = %s",
        [skeleton_id],
    ).fetchone()
    if row is None:
        raise NotFound(f"no skeleton {skeleton_id}")
    skeleton = Skeleton.from_row(row[1], row[2], row[3], name=row[0] or "")
    try:
        data = gltf_bytes(rest_motion(skeleton))
    except ValueError as e:  # no bone long enough to draw
        raise NotFound(f"skeleton {skeleton_id} has no character: {e}") from None
    return file_response(data, f"skeleton_{skeleton_id}", "glb")
