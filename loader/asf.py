"""Acclaim ASF (skeleton) and AMC (motion) reader into the shared `Motion` model.

Conventions of the format, as CMU's files use it:
- `:units length L`: one length unit is 0.0254 / L metres; `angle deg|rad` for every angle.
- A bone has a rest `direction` and `length` in world axes, and `axis ax ay az ORDER`, the
  orientation C of its local frame; AMC values are Euler angles M in that local frame, for the
  bone's `dof` in the order listed, applied first-listed first (rx ry rz -> M = Rz Ry Rx). The
  bone's rotation relative to its parent, in world-aligned rest axes, is C M C^-1: this is what we
  store, so forward kinematics is the same code as for BVH.
- A bone's FK position is its tip. Our joint for a bone sits at the bone's start (its parent's
  tip), so the knee is `ltibia`; a joint's offset is the parent bone's vector, and a leaf's own
  vector is its End Site.

Malformed input is a MotionFileError naming file and line: among others a :hierarchy that gives a
bone two parents, makes a bone its own parent or root a child, or closes a cycle; a repeated dof,
root channel or axis letter; a tree deeper than limits.MAX_JOINT_DEPTH (walked without recursion);
lengths beyond limits.MAX_LENGTH_M; and an --fps outside limits.FPS_RANGE.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from modb.motion import Joint, Motion, Skeleton, Source
from modb_kernel import quaternion

from .errors import MotionFileError
from .skeleton_maps import guess_joint_map, guess_mirror_pairs
from .text import lines_of
from .limits import FPS_RANGE_TEXT, MAX_JOINT_DEPTH, MAX_LENGTH_M, fps_in_range
from .units import NAMED_UNITS

DEFAULT_FPS = 120.0  # AMC files carry no rate; CMU captured at 120 fps
_ROTATION_DOFS = ("rx", "ry", "rz")
_TRANSLATION_DOFS = ("tx", "ty", "tz")


@dataclass
class AsfBone:
    name: str
    line: int
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    length: float = 0.0
    axis: np.ndarray = field(default_factory=lambda: np.zeros(3))  # radians
    axis_order: str = "XYZ"
    dofs: list[str] = field(default_factory=list)


@dataclass
class AsfSkeleton:
    path: str  # names the file in errors
    stored_as: str  # names it in the catalogue (load_params' skeleton_file)
    sha256: str
    unit_m: float
    units_rule: str
    angle_scale: float  # radians per file angle unit
    root_order: list[str]
    root_axis_order: str
    root_position: np.ndarray
    root_orientation: np.ndarray  # radians
    bones: dict[str, AsfBone]
    children: dict[str, list[str]]

    def joint_order(self) -> list[str]:
        """'root' then the bones depth-first in :hierarchy order (iterative: depth costs no
        recursion; a name is listed once even if the hierarchy were to repeat it)."""
        order: list[str] = []
        seen: set[str] = set()
        todo = ["root"]
        while todo:
            name = todo.pop()
            if name in seen:
                continue
            seen.add(name)
            order.append(name)
            todo.extend(reversed(self.children.get(name, [])))
        return order


def _numbers(path: str, line: int, words: list[str], count: int, what: str) -> np.ndarray:
    if len(words) < count:
        raise MotionFileError(path, line, f"{what} needs {count} numbers, found {len(words)}")
    try:
        values = np.array([float(w) for w in words[:count]])
    except ValueError:
        raise MotionFileError(
            path, line, f"{what} has a value that is not a number: {' '.join(words[:count])!r}"
        )
    if not np.all(np.isfinite(values)):
        raise MotionFileError(path, line, f"{what} is not finite: {' '.join(words[:count])!r}")
    return values


def _repeated(items: list[str]) -> str | None:
    """The first item listed a second time, or None."""
    seen: set[str] = set()
    for item in items:
        if item in seen:
            return item
        seen.add(item)
    return None


def _axis_order(path: str, line: int, word: str) -> str:
    order = word.upper()
    if not quaternion.is_supported_order(order) or len(order) != 3:
        raise MotionFileError(path, line, f"axis order {word!r} is not a permutation of XYZ")
    return order


def _sections(lines: list[str]) -> list[tuple[str, list[tuple[int, list[str]]]]]:
    """(':keyword', [(line number, words), ...]) per section, comments and blank lines dropped."""
    sections: list[tuple[str, list[tuple[int, list[str]]]]] = []
    for number, text in enumerate(lines, start=1):
        words = text.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0].startswith(":"):
            sections.append((words[0].lower(), [(number, words[1:])] if len(words) > 1 else []))
        elif sections:
            sections[-1][1].append((number, words))
    return sections


def read_asf(path: str, units: str | float = "auto") -> AsfSkeleton:
    with open(path, "rb") as f:
        return parse_asf(f.read(), path, units)


def parse_asf(
    raw: bytes, path: str, units: str | float = "auto", stored_as: str | None = None
) -> AsfSkeleton:
    """An ASF file's bytes into its skeleton; `path` names it in errors, `stored_as` in the
    catalogue (default: its absolute path). Raises MotionFileError."""
    lines = lines_of(raw)
    sections = _sections(lines)
    if not any(k == ":bonedata" for k, _ in sections):
        raise MotionFileError(path, 1, "no :bonedata section", "not an ASF skeleton file")
    length_scale, length_line, angle = 1.0, 0, "deg"
    root_order = ["TX", "TY", "TZ", "RX", "RY", "RZ"]
    root_axis, root_position, root_orientation = "XYZ", np.zeros(3), np.zeros(3)
    root_position_line = 0
    bones: dict[str, AsfBone] = {}
    children: dict[str, list[str]] = {}
    parent_of: dict[str, tuple[str, int]] = {}  # bone -> (parent, line of the :hierarchy entry)
    for keyword, body in sections:
        if keyword == ":units":
            for line, words in body:
                if words[0] == "length":
                    length_scale = float(_numbers(path, line, words[1:], 1, "units length")[0])
                    length_line = line
                    if length_scale <= 0:
                        raise MotionFileError(path, line, "units length must be positive")
                elif words[0] == "angle":
                    angle = words[1].lower() if len(words) > 1 else ""
                    if angle not in ("deg", "rad"):
                        raise MotionFileError(
                            path, line, f"angle unit {angle!r} is neither deg nor rad"
                        )
        elif keyword == ":root":
            for line, words in body:
                key = words[0].lower()
                if key == "order":
                    root_order = [w.upper() for w in words[1:]]
                    unknown = [
                        w for w in root_order if w.lower() not in _ROTATION_DOFS + _TRANSLATION_DOFS
                    ]
                    if unknown:
                        raise MotionFileError(
                            path,
                            line,
                            f"unknown root channel {unknown[0]!r}",
                            "root order uses TX TY TZ RX RY RZ",
                        )
                    twice = _repeated(root_order)
                    if twice:
                        raise MotionFileError(
                            path,
                            line,
                            f"root channel {twice} appears twice in the root order",
                            "each of TX TY TZ RX RY RZ may appear once",
                        )
                elif key == "axis":
                    root_axis = _axis_order(path, line, words[1] if len(words) > 1 else "")
                elif key == "position":
                    root_position = _numbers(path, line, words[1:], 3, "root position")
                    root_position_line = line
                elif key == "orientation":
                    root_orientation = _numbers(path, line, words[1:], 3, "root orientation")
        elif keyword == ":bonedata":
            bone: AsfBone | None = None
            for line, words in body:
                key = words[0].lower()
                if key == "begin":
                    bone = AsfBone(name="", line=line)
                elif key == "end":
                    if bone is None or not bone.name:
                        raise MotionFileError(path, line, "bone without a name")
                    if bone.name == "root":
                        raise MotionFileError(
                            path,
                            bone.line,
                            "a bone is named 'root'",
                            "root is the :root section; give the bone another name",
                        )
                    if bone.name in bones:
                        raise MotionFileError(
                            path,
                            bone.line,
                            f"bone name {bone.name!r} is used twice "
                            f"(first on line {bones[bone.name].line})",
                        )
                    bones[bone.name] = bone
                    bone = None
                elif bone is None:
                    raise MotionFileError(
                        path, line, f"{words[0]!r} outside a begin/end bone block"
                    )
                elif key == "name":
                    bone.name = words[1] if len(words) > 1 else ""
                elif key == "direction":
                    bone.direction = _numbers(path, line, words[1:], 3, f"{bone.name} direction")
                elif key == "length":
                    bone.length = float(
                        _numbers(path, line, words[1:], 1, f"{bone.name} length")[0]
                    )
                elif key == "axis":
                    bone.axis = _numbers(path, line, words[1:], 3, f"{bone.name} axis")
                    bone.axis_order = _axis_order(path, line, words[4] if len(words) > 4 else "XYZ")
                elif key == "dof":
                    bone.dofs = [w.lower() for w in words[1:]]
                    bad = [d for d in bone.dofs if d not in _ROTATION_DOFS]
                    if bad:
                        hint = (
                            "bone translation and stretch dofs are not supported"
                            if bad[0] in _TRANSLATION_DOFS + ("l",)
                            else "dofs are rx ry rz"
                        )
                        raise MotionFileError(
                            path, line, f"unsupported dof {bad[0]!r} on bone {bone.name}", hint
                        )
                    twice = _repeated(bone.dofs)
                    if twice:
                        raise MotionFileError(
                            path,
                            line,
                            f"dof {twice} appears twice on bone {bone.name}",
                            "each of rx ry rz may appear once",
                        )
            if bone is not None:
                raise MotionFileError(
                    path,
                    len(lines),
                    f"bone {bone.name or '?'} has no 'end'",
                    "the file is truncated",
                )
        elif keyword == ":hierarchy":
            for line, words in body:
                if words[0].lower() in ("begin", "end"):
                    continue
                parent, kids = words[0], words[1:]
                for name in (parent, *kids):
                    if name != "root" and name not in bones:
                        raise MotionFileError(
                            path, line, f"hierarchy names bone {name!r}, which :bonedata lacks"
                        )
                for kid in kids:
                    _check_parent(path, line, parent, kid, parent_of)
                    parent_of[kid] = (parent, line)
                children.setdefault(parent, []).extend(kids)
    scale = np.pi / 180.0 if angle == "deg" else 1.0
    for b in bones.values():
        b.axis = b.axis * scale
    if isinstance(units, float):
        unit_m, rule = (
            units,
            f"--units {units:g}: {units:g} m per unit (the ASF says length {length_scale:g})",
        )
    elif units != "auto":
        unit_m, rule = NAMED_UNITS[units], f"--units {units}: {NAMED_UNITS[units]:g} m per unit"
    else:
        unit_m = 0.0254 / length_scale
        if not np.isfinite(unit_m):  # a subnormal length
            raise MotionFileError(
                path,
                length_line,
                f"units length {length_scale:g} makes one unit {unit_m} m",
                "one unit is 0.0254 / length metres: CMU uses length 0.45",
            )
        rule = (
            f"ASF :units length {length_scale:g}: "
            f"one unit is 0.0254/{length_scale:g} = {unit_m:.7g} m"
        )
    skeleton = AsfSkeleton(
        path=path,
        stored_as=stored_as or os.path.abspath(path),
        sha256=hashlib.sha256(raw).hexdigest(),
        unit_m=unit_m,
        units_rule=rule,
        angle_scale=scale,
        root_order=root_order,
        root_axis_order=root_axis,
        root_position=root_position,
        root_orientation=root_orientation * scale,
        bones=bones,
        children=children,
    )
    _check_tree(skeleton, parent_of)
    _check_lengths(skeleton, root_position_line)
    return skeleton


def _check_parent(
    path: str, line: int, parent: str, kid: str, parent_of: dict[str, tuple[str, int]]
) -> None:
    """One :hierarchy edge parent -> kid: root is nobody's child, a bone has one parent."""
    if kid == "root":
        raise MotionFileError(
            path,
            line,
            f"root is given as a child of {parent}",
            "root is the top of the hierarchy: it has no parent",
        )
    if kid == parent:
        raise MotionFileError(path, line, f"bone {kid!r} is given as its own parent")
    if kid in parent_of:
        first, first_line = parent_of[kid]
        again = "again" if first == parent else f"a second parent, {parent}"
        raise MotionFileError(
            path,
            line,
            f"bone {kid!r} is given {again} (line {first_line} made it a child of {first})",
            "a bone has one parent: list it once in :hierarchy",
        )


def _check_tree(asf: AsfSkeleton, parent_of: dict[str, tuple[str, int]]) -> None:
    """Every bone descends from root, without a cycle, at most MAX_JOINT_DEPTH joints deep."""
    depth = {"root": 1}
    for name in asf.joint_order()[1:]:
        parent, line = parent_of[name]
        depth[name] = depth[parent] + 1
        if depth[name] > MAX_JOINT_DEPTH:
            raise MotionFileError(
                asf.path,
                line,
                f"bone {name} is {depth[name]} joints deep, more than the {MAX_JOINT_DEPTH} "
                "accepted",
                "the :hierarchy is damaged",
            )
    for bone in asf.bones.values():
        if bone.name in depth:
            continue
        # Not under root: its chain of parents ends in a bone without one, or runs in a circle.
        chain = [bone.name]
        while chain[-1] in parent_of and parent_of[chain[-1]][0] not in chain:
            chain.append(parent_of[chain[-1]][0])
        if chain[-1] in parent_of:
            start = chain.index(parent_of[chain[-1]][0])
            loop = chain[start:][::-1]  # each bone the parent of the next
            closing = max(range(len(loop)), key=lambda k: parent_of[loop[k]][1])
            line = parent_of[loop[closing]][1]
            loop = loop[closing - 1 :] + loop[: closing - 1]  # from that line's parent
            raise MotionFileError(
                asf.path,
                line,
                "the :hierarchy has a cycle: " + " -> ".join([*loop, loop[0]]),
                "a bone cannot descend from itself; every bone descends from root",
            )
        raise MotionFileError(
            asf.path,
            bone.line,
            f"bone {bone.name!r} is not in the :hierarchy"
            + (f" (its ancestor {chain[-1]} has no parent)" if len(chain) > 1 else ""),
            "every bone descends from root",
        )


def _check_lengths(asf: AsfSkeleton, root_position_line: int) -> None:
    """Refuse a bone vector or root position beyond MAX_LENGTH_M, naming its line."""
    hint = "the value is damaged, or the units are wrong: see :units length, or --units"
    metres = float(np.max(np.abs(asf.root_position))) * asf.unit_m
    if not metres <= MAX_LENGTH_M:
        raise MotionFileError(
            asf.path,
            root_position_line or None,
            f"root position is {metres:.4g} m from the origin, beyond the {MAX_LENGTH_M:,g} m "
            "accepted",
            hint,
        )
    for bone in asf.bones.values():
        metres = float(np.max(np.abs(bone.direction))) * abs(bone.length) * asf.unit_m
        if not metres <= MAX_LENGTH_M:
            raise MotionFileError(
                asf.path,
                bone.line,
                f"bone {bone.name} (direction x length) is {metres:.4g} m long, beyond the "
                f"{MAX_LENGTH_M:,g} m accepted",
                hint,
            )


def _local_rotation(
    c_angles: np.ndarray, c_order: str, m_angles: np.ndarray, m_order: str
) -> np.ndarray:
    """C M C^-1 for rest axis C and motion M, both applied first-listed first (XYZ -> Rz Ry Rx)."""
    c = quaternion.from_euler(c_angles[::-1], c_order[::-1])
    if len(m_order):
        m = quaternion.from_euler(m_angles[..., ::-1], m_order[::-1])
    else:
        m = np.tile([1.0, 0.0, 0.0, 0.0], m_angles.shape[:-1] + (1,))
    return quaternion.canonical(
        quaternion.multiply(quaternion.multiply(c, m), quaternion.conjugate(c))
    )


def _skeleton(asf: AsfSkeleton, name: str) -> Skeleton:
    order = asf.joint_order()
    index = {n: k for k, n in enumerate(order)}
    parent_of = {kid: parent for parent, kids in asf.children.items() for kid in kids}
    joints = [
        Joint(
            name="root",
            parent=-1,
            offset=tuple(asf.root_position * asf.unit_m),
            channels=tuple(asf.root_order),
            rotation_order="".join(c[1] for c in asf.root_order if c.startswith("R")),
        )
    ]
    for n in order[1:]:
        bone = asf.bones[n]
        parent = parent_of[n]
        offset = (
            np.zeros(3)
            if parent == "root"
            else asf.bones[parent].direction * asf.bones[parent].length * asf.unit_m
        )
        joints.append(
            Joint(
                name=n,
                parent=index[parent],
                offset=tuple(float(v) for v in offset),
                channels=tuple(bone.dofs),
                rotation_order="".join(d[1].upper() for d in bone.dofs),
                end_site=None
                if asf.children.get(n)
                else tuple(float(v) for v in bone.direction * bone.length * asf.unit_m),
            )
        )
    names = [j.name for j in joints]
    return Skeleton(
        joints=joints,
        unit_m=asf.unit_m,
        source_format="asf",
        joint_map=guess_joint_map(names, [j.parent for j in joints]),
        mirror_pairs=guess_mirror_pairs(names),
        name=os.path.splitext(os.path.basename(asf.path))[0],
    )


def _check_fps(path: str, fps: float) -> None:
    if not fps_in_range(fps):
        raise MotionFileError(
            path,
            None,
            f"frame rate {fps:g} fps (--fps) is outside the accepted {FPS_RANGE_TEXT}",
            "AMC files carry no rate: pass --fps within that range (CMU captured at 120 fps)",
        )


def read_amc(
    path: str,
    asf: AsfSkeleton,
    fps: float = DEFAULT_FPS,
    allow_truncated: bool = False,
    warn: Callable[[str], None] | None = None,
) -> Motion:
    """Parse an AMC file against its ASF skeleton. Raises MotionFileError naming file and line."""
    _check_fps(path, fps)  # before the file is opened, as its errors come after this one
    with open(path, "rb") as f:
        return parse_amc(f.read(), path, asf, fps, allow_truncated, warn)


def parse_amc(
    raw: bytes,
    path: str,
    asf: AsfSkeleton,
    fps: float = DEFAULT_FPS,
    allow_truncated: bool = False,
    warn: Callable[[str], None] | None = None,
    stored_as: str | None = None,
) -> Motion:
    """An AMC file's bytes against its ASF skeleton; `path` names it in errors, `stored_as` in the
    catalogue (default: its absolute path). Raises MotionFileError naming file and line."""
    _check_fps(path, fps)
    lines = lines_of(raw)
    angle_scale = asf.angle_scale
    frames: list[dict[str, tuple[int, list[str]]]] = []
    frame_lines: list[int] = []
    for number, text in enumerate(lines, start=1):
        words = text.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0].startswith(":"):
            if words[0].upper() == ":RADIANS":
                angle_scale = 1.0
            elif words[0].upper() == ":DEGREES":
                angle_scale = np.pi / 180.0
            continue
        if len(words) == 1 and words[0].isdigit():
            frames.append({})
            frame_lines.append(number)
            continue
        if not frames:
            raise MotionFileError(
                path,
                number,
                f"expected a frame number, found {text.strip()[:40]!r}",
                "an AMC file lists a frame number, then one line per bone",
            )
        bone = words[0]
        if bone != "root" and bone not in asf.bones:
            raise MotionFileError(
                path,
                number,
                f"bone {bone!r} is not in the skeleton {asf.path}",
                "is this AMC paired with the right ASF? (--asf FILE)",
            )
        if bone in frames[-1]:
            raise MotionFileError(
                path, number, f"bone {bone!r} appears twice in frame {len(frames)}"
            )
        frames[-1][bone] = (number, words[1:])
    if not frames:
        raise MotionFileError(path, 1, "no frames", "expected an AMC motion file")
    expected = {
        "root": len(asf.root_order),
        **{n: len(b.dofs) for n, b in asf.bones.items() if b.dofs},
    }
    for k, frame in enumerate(frames):
        missing = [n for n in expected if n not in frame]
        if missing:
            last = k == len(frames) - 1
            if last and allow_truncated and k > 0:
                if warn:
                    warn(
                        f"{path}:{frame_lines[k]}: dropped the last frame, cut short "
                        f"({len(frame)} of {len(expected)} bone lines)"
                    )
                frames.pop()
                break
            raise MotionFileError(
                path,
                frame_lines[k],
                f"frame {k + 1} lacks {len(missing)} of {len(expected)} bone lines "
                f"({', '.join(missing[:4])}{'...' if len(missing) > 4 else ''})",
                "the file is cut short: --allow-truncated drops an incomplete last frame"
                if last
                else "every frame lists every bone with degrees of freedom",
            )
    n_frames = len(frames)
    values: dict[str, np.ndarray] = {}
    for bone, count in expected.items():
        rows = [frame[bone] for frame in frames]
        bad = next(((line, words) for line, words in rows if len(words) != count), None)
        if bad:
            raise MotionFileError(
                path, bad[0], f"bone {bone} has {len(bad[1])} values, its dof needs {count}"
            )
        try:
            values[bone] = np.array([words for _, words in rows], dtype=np.float64)
        except ValueError:
            for line, words in rows:
                for w in words:
                    try:
                        float(w)
                    except ValueError:
                        raise MotionFileError(
                            path, line, f"value {w!r} of bone {bone} is not a number"
                        ) from None
            raise MotionFileError(  # numpy refused a value that float() reads
                path, rows[0][0], f"the values of bone {bone} could not be read"
            ) from None
        if not np.all(np.isfinite(values[bone])):
            line = rows[int(np.argwhere(~np.isfinite(values[bone]))[0, 0])][0]
            raise MotionFileError(path, line, f"bone {bone} has a value that is not finite")

    skeleton = _skeleton(asf, os.path.splitext(os.path.basename(path))[0])
    rotations = np.empty((n_frames, len(skeleton.joints), 4))
    root = values["root"]
    channel = {c: k for k, c in enumerate(asf.root_order)}
    translation = asf.root_position[None, :].repeat(n_frames, axis=0)
    for axis, c in enumerate(("TX", "TY", "TZ")):
        if c in channel:
            translation[:, axis] = root[:, channel[c]]
    far = np.argwhere(~(np.abs(translation) <= MAX_LENGTH_M / asf.unit_m))
    if len(far):
        k, axis = far[0]
        raise MotionFileError(
            path,
            frames[k]["root"][0],
            f"root {'XYZ'[axis]} position of frame {k + 1} is "
            f"{abs(translation[k, axis]) * asf.unit_m:.4g} m, beyond the {MAX_LENGTH_M:,g} m "
            "accepted",
            "the value is damaged, or the units are wrong: see :units length, or --units",
        )
    root_rot = [c for c in asf.root_order if c.startswith("R")]
    rotations[:, 0] = _local_rotation(
        asf.root_orientation,
        asf.root_axis_order,
        root[:, [channel[c] for c in root_rot]] * angle_scale,
        "".join(c[1] for c in root_rot),
    )
    for k, joint in enumerate(skeleton.joints[1:], start=1):
        bone = asf.bones[joint.name]
        m = values[joint.name] * angle_scale if bone.dofs else np.zeros((n_frames, 0))
        rotations[:, k] = _local_rotation(bone.axis, bone.axis_order, m, joint.rotation_order)
    return Motion(
        skeleton=skeleton,
        fps=fps,
        rotations=rotations,
        translations=(translation * asf.unit_m)[:, None, :],
        name=os.path.splitext(os.path.basename(path))[0],
        source=Source(
            path=stored_as or os.path.abspath(path),
            sha256=hashlib.sha256(raw).hexdigest(),
            units_rule=asf.units_rule,
        ),
        meta={
            "frame_time": 1.0 / fps,
            "skeleton_file": asf.stored_as,
            "skeleton_sha256": asf.sha256,
        },
    )
