"""Writing a Motion as glTF 2.0 (`.glb` binary or `.gltf` JSON, by the file name), with pygltflib.

The skeleton becomes a skin: one node per joint (rest offsets as translations), inverse bind
matrices of the rest pose (every rotation the identity, as the skeleton is stored). A character mesh
is made from the skeleton itself, a capsule along every bone, each vertex bound to the bone's joint,
so any engine or three.js shows a skinned character with no third-party model. The animation has a
rotation channel per joint (glTF's x, y, z, w order) and a translation channel for every joint
whose translation varies. Units are metres, +Y up, and the character faces +Z at heading 0, as glTF
asks.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import pygltflib as gl
from modb_kernel import kinematics

from modb.motion import Motion, Skeleton
from modb.output import open_output
from modb.provenance import credits

CAPSULE_SIDES = 10  # around a bone
CAPSULE_CAP_RINGS = 3  # per hemisphere
MIN_BONE_M = 0.01  # shorter bones (zero-length helpers) get no capsule


def _capsule(start: np.ndarray, end: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of a capsule from start to end: a cylinder, hemispherical caps."""
    axis = end - start
    length = float(np.linalg.norm(axis))
    direction = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    u = np.cross(direction, helper)
    u /= np.linalg.norm(u)
    v = np.cross(direction, u)
    # rings from the start's pole to the end's (distance along the axis, radius): the start's
    # hemisphere up to its equator at 0, then the end's from its equator at `length`
    caps = np.linspace(0.0, np.pi / 2, CAPSULE_CAP_RINGS + 1)[1:]
    rings = [(-radius * np.cos(a), radius * np.sin(a)) for a in caps]
    rings += [(length + radius * np.cos(a), radius * np.sin(a)) for a in caps[::-1]]
    angles = np.linspace(0.0, 2 * np.pi, CAPSULE_SIDES, endpoint=False)
    circle = np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v
    vertices = [start - radius * direction]
    for along, r in rings:
        vertices.extend(start + along * direction + r * circle)
    vertices.append(end + radius * direction)
    vertices = np.array(vertices)
    triangles = []
    s = CAPSULE_SIDES
    for k in range(s):  # the start's fan
        triangles.append((0, 1 + (k + 1) % s, 1 + k))
    for ring in range(len(rings) - 1):
        a, b = 1 + ring * s, 1 + (ring + 1) * s
        for k in range(s):
            k1 = (k + 1) % s
            triangles += [(a + k, a + k1, b + k), (a + k1, b + k1, b + k)]
    last, tip = 1 + (len(rings) - 1) * s, len(vertices) - 1
    for k in range(s):  # the end's fan
        triangles.append((last + k, last + (k + 1) % s, tip))
    return vertices, np.array(triangles)


def character_mesh(motion: Motion, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (around the joints' `rest` positions, metres), triangles, and the joint each vertex
    is bound to."""
    sk = motion.skeleton
    height = float(np.ptp(rest[:, 1])) or 1.0
    above = set(sk.above_pelvis())  # no limb from these: frames of reference, not the body
    bones = [
        (j.parent, rest[j.parent], rest[k])
        for k, j in enumerate(sk.joints)
        if j.parent >= 0 and j.parent not in above
    ]
    bones += [
        (k, rest[k], rest[k] + np.asarray(j.end_site))
        for k, j in enumerate(sk.joints)
        if j.end_site is not None
    ]
    vertices, triangles, joints = [], [], []
    for joint, start, end in bones:
        length = float(np.linalg.norm(end - start))
        if length < MIN_BONE_M:
            continue
        v, t = _capsule(start, end, min(0.035 * height, 0.2 * length + 0.01))
        triangles.append(t + sum(len(x) for x in vertices))
        vertices.append(v)
        joints.append(np.full(len(v), joint))
    if not vertices:
        raise ValueError("the skeleton has no bone of 1 cm or more to draw a character from")
    return np.concatenate(vertices), np.concatenate(triangles), np.concatenate(joints)


class _Buffer:
    """One binary buffer that accessors are appended to (4-byte aligned, as glTF requires)."""

    def __init__(self, gltf: gl.GLTF2) -> None:
        self.gltf, self.data = gltf, bytearray()

    def add(
        self,
        array: np.ndarray,
        kind: str,
        component: int,
        target: int | None = None,
        bounds: bool = False,
    ) -> int:
        array = np.ascontiguousarray(array)
        view = gl.BufferView(
            buffer=0, byteOffset=len(self.data), byteLength=array.nbytes, target=target
        )
        self.data += array.tobytes()
        self.data += b"\0" * (-len(self.data) % 4)
        self.gltf.bufferViews.append(view)
        flat = array.reshape(len(array), -1)
        accessor = gl.Accessor(
            bufferView=len(self.gltf.bufferViews) - 1,
            componentType=component,
            count=len(array),
            type=kind,
            min=flat.min(axis=0).tolist() if bounds else None,
            max=flat.max(axis=0).tolist() if bounds else None,
        )
        self.gltf.accessors.append(accessor)
        return len(self.gltf.accessors) - 1


def _animation(buffer: _Buffer, motion: Motion) -> gl.Animation:
    """The motion as an animation: a time per frame, a rotation per joint, moving translations."""
    times = buffer.add(
        (np.arange(motion.n_frames) / motion.fps).astype(np.float32)[:, None],
        gl.SCALAR,
        gl.FLOAT,
        bounds=True,
    )
    translated = motion.skeleton.translated
    samplers, channels = [], []

    def channel(node: int, path: str, values: np.ndarray, kind: str) -> None:
        samplers.append(
            gl.AnimationSampler(
                input=times,
                output=buffer.add(values.astype(np.float32), kind, gl.FLOAT),
                interpolation="LINEAR",
            )
        )
        channels.append(
            gl.AnimationChannel(
                sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=node, path=path)
            )
        )

    for k in range(len(motion.skeleton.joints)):
        wxyz = motion.rotations[:, k]
        channel(k, "rotation", np.concatenate([wxyz[:, 1:], wxyz[:, :1]], axis=1), gl.VEC4)
        if k in translated:
            local = motion.translations[:, translated.index(k)]
            if np.ptp(local, axis=0).max() > 1e-9:
                channel(k, "translation", local, gl.VEC3)
    return gl.Animation(name=motion.name or "motion", samplers=samplers, channels=channels)


def to_gltf(motion: Motion, also: Sequence[Motion] = ()) -> gl.GLTF2:
    """The motion on a skinned character of its skeleton; `also`, motions of the same skeleton
    (a model's samples), as further animations of the same character."""
    sk = motion.skeleton
    n_joints = len(sk.joints)
    gltf = gl.GLTF2(asset=gl.Asset(version="2.0", generator="modb"), scene=0)
    sources = motion.meta.get("sources")
    if sources:  # a strip's sources and their terms (modb.provenance)
        gltf.asset.copyright = credits(sources)
        gltf.asset.extras = {"sources": sources}
    buffer = _Buffer(gltf)
    translated = sk.translated
    rest_local = sk.offsets.copy()
    rest_local[translated] = motion.translations[0]  # a translated joint rests where it starts
    children: dict[int, list[int]] = {k: [] for k in range(n_joints)}
    for k, j in enumerate(sk.joints):
        if j.parent >= 0:
            children[j.parent].append(k)
    gltf.nodes = [
        gl.Node(name=j.name, translation=rest_local[k].tolist(), children=children[k] or None)
        for k, j in enumerate(sk.joints)
    ]
    # The bind pose: every rotation the identity, the joints at their first frame's offsets, the
    # top joint at the origin.
    bind_local = rest_local.copy()
    bind_local[0] = sk.offsets[0]
    bind = kinematics.rest_positions(sk.parents, bind_local)
    inverse_bind = np.tile(np.eye(4, dtype=np.float32), (n_joints, 1, 1))
    inverse_bind[:, 3, :3] = -bind  # column-major: the translation is the fourth column
    vertices, triangles, vertex_joint = character_mesh(motion, bind)
    attributes = gl.Attributes(
        POSITION=buffer.add(
            vertices.astype(np.float32), gl.VEC3, gl.FLOAT, gl.ARRAY_BUFFER, bounds=True
        ),
        JOINTS_0=buffer.add(
            np.stack([vertex_joint, *[np.zeros_like(vertex_joint)] * 3], axis=1).astype(np.uint16),
            gl.VEC4,
            gl.UNSIGNED_SHORT,
            gl.ARRAY_BUFFER,
        ),
        WEIGHTS_0=buffer.add(
            np.tile(np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32), (len(vertices), 1)),
            gl.VEC4,
            gl.FLOAT,
            gl.ARRAY_BUFFER,
        ),
    )
    indices = buffer.add(
        triangles.reshape(-1).astype(np.uint32), gl.SCALAR, gl.UNSIGNED_INT, gl.ELEMENT_ARRAY_BUFFER
    )
    gltf.materials = [
        gl.Material(
            name="character",
            alphaCutoff=None,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[0.72, 0.74, 0.78, 1.0], metallicFactor=0.0, roughnessFactor=0.8
            ),
        )
    ]
    gltf.meshes = [
        gl.Mesh(
            name="character",
            primitives=[gl.Primitive(attributes=attributes, indices=indices, material=0)],
        )
    ]
    gltf.skins = [
        gl.Skin(
            name=sk.name or "skeleton",
            joints=list(range(n_joints)),
            skeleton=0,
            inverseBindMatrices=buffer.add(inverse_bind, gl.MAT4, gl.FLOAT),
        )
    ]
    gltf.nodes.append(gl.Node(name="character", mesh=0, skin=0))
    gltf.scenes = [gl.Scene(nodes=[0, n_joints])]
    gltf.animations = [_animation(buffer, m) for m in (motion, *also)]
    gltf.buffers = [gl.Buffer(byteLength=len(buffer.data))]
    gltf.set_binary_blob(bytes(buffer.data))
    return gltf


def gltf_bytes(motion: Motion, binary: bool = True, also: Sequence[Motion] = ()) -> bytes:
    """The file: `.glb` (binary) or `.gltf` JSON with its buffer embedded as a data URI."""
    gltf = to_gltf(motion, also)
    if binary:
        return b"".join(gltf.save_to_bytes())
    gltf.convert_buffers(gl.BufferFormat.DATAURI)
    return gltf.gltf_to_json().encode("utf-8")


def write_gltf_file(
    motion: Motion, path: str | os.PathLike, allow_stdout: bool = False, also: Sequence[Motion] = ()
) -> None:
    """Writes `motion` (and `also`, as further animations) to `path` through open_output: `.gltf`
    JSON, anything else (`.glb`, `-` for standard output) binary."""
    data = gltf_bytes(motion, not os.fspath(path).lower().endswith(".gltf"), also)
    with open_output(path, "wb", allow_stdout=allow_stdout) as f:
        f.write(data)


def rest_motion(skeleton: Skeleton, fps: float = 30.0) -> Motion:
    """One frame of the skeleton at rest (every rotation the identity): its character, unposed."""
    rotations = np.zeros((1, len(skeleton.joints), 4))
    rotations[..., 0] = 1.0
    translations = skeleton.offsets[skeleton.translated][None]
    return Motion(skeleton, fps, rotations, translations, name=skeleton.name or "skeleton")


def is_gltf_name(path: str | os.PathLike) -> bool:
    return os.fspath(path).lower().endswith((".glb", ".gltf"))
