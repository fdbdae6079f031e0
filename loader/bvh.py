"""BVH reader: hierarchy and motion into the shared `Motion` model.

Handles what real files contain: any rotation channel order per joint,
position channels on any joint (their values replace the joint's offset, as
in bvhio and most tools), End Sites, CRLF, tabs (also inside `Frame Time:`),
numbers like `.0083333`, and colons in joint names. Names may not contain whitespace.

Anything else is a MotionFileError naming file and line: among others a channel listed twice on
a joint, a frame rate outside limits.FPS_RANGE, a hierarchy deeper than limits.MAX_JOINT_DEPTH (it
is read with an explicit stack, not recursion), and lengths beyond limits.MAX_LENGTH_M.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field

import numpy as np

from modb.motion import Joint, Motion, Skeleton, Source
from modb_kernel import quaternion

from .errors import MotionFileError
from .skeleton_maps import guess_joint_map, guess_mirror_pairs
from .text import lines_of
from .limits import FPS_RANGE_TEXT, MAX_JOINT_DEPTH, MAX_LENGTH_M, fps_in_range
from .units import UnitsError, resolve_units

_CHANNELS = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"}
# The MOTION header's two lines; any whitespace (spaces, tabs) between and after the words.
_HEADER = (
    ("Frames:", re.compile(r"Frames\s*:(.*)")),
    ("Frame Time:", re.compile(r"Frame\s+Time\s*:(.*)")),
)


@dataclass
class _RawJoint:
    name: str
    parent: int
    line: int
    depth: int  # the root is 1
    offset: list[float] = field(default_factory=list)
    offset_line: int = 0
    channels: list[str] = field(default_factory=list)
    end_site: list[float] | None = None
    end_site_line: int = 0


class _Tokens:
    """Whitespace tokens of the HIERARCHY section with their 1-based line numbers."""

    def __init__(self, path: str, lines: list[str]):
        self.path = path
        self.items: list[tuple[str, int]] = []
        self.motion_line = 0
        for number, line in enumerate(lines, start=1):
            words = line.split()
            if words[:1] == ["MOTION"]:
                self.motion_line = number
                break
            self.items.extend((w, number) for w in words)
        self.pos = 0

    def error(self, message: str, hint: str = "") -> MotionFileError:
        line = self.items[min(self.pos, len(self.items) - 1)][1] if self.items else 1
        return MotionFileError(self.path, line, message, hint)

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            raise MotionFileError(
                self.path,
                self.items[-1][1] if self.items else 1,
                f"file ends inside the hierarchy, expected {what}",
                "the file is truncated or not a BVH file",
            )
        item = self.items[self.pos]
        self.pos += 1
        return item

    def expect(self, word: str) -> int:
        token, line = self.next(repr(word))
        if token != word:
            self.pos -= 1
            raise self.error(f"expected {word!r}, found {token!r}")
        return line

    def number(self, what: str, joint: str) -> float:
        """The next token as a finite number; `what` and `joint` only go into an error (cheap)."""
        if self.pos >= len(self.items):
            self.next(f"{joint} {what}")
        token = self.items[self.pos][0]
        self.pos += 1
        try:
            value = float(token)
        except ValueError:
            self.pos -= 1
            raise self.error(f"expected a number for {joint} {what}, found {token!r}") from None
        if value - value != 0.0:  # inf or nan
            self.pos -= 1
            raise self.error(f"{joint} {what} is {token}, not a finite number")
        return value


def _open_joint(
    tokens: _Tokens, name: str, parent: int, line: int, joints: list[_RawJoint]
) -> None:
    """A joint's name is read: its '{', OFFSET and CHANNELS (its children follow)."""
    depth = joints[parent].depth + 1 if parent >= 0 else 1
    if depth > MAX_JOINT_DEPTH:
        raise MotionFileError(
            tokens.path,
            line,
            f"joint {name} is {depth} joints deep, more than the {MAX_JOINT_DEPTH} accepted",
            "a '}' closing a joint is probably missing above this line",
        )
    joint = _RawJoint(name=name, parent=parent, line=line, depth=depth)
    joints.append(joint)
    tokens.expect("{")
    joint.offset_line = tokens.expect("OFFSET")
    joint.offset = [tokens.number("OFFSET", name) for _ in range(3)]
    token, _ = tokens.next("CHANNELS or a child joint")
    if token != "CHANNELS":
        tokens.pos -= 1
        return
    count = tokens.number("CHANNELS count", name)
    if count != int(count) or not 0 <= count <= 6:
        raise tokens.error(f"channel count of {name} must be a whole number 0-6, found {count:g}")
    for _ in range(int(count)):
        channel, _ = tokens.next("a channel name")
        if channel not in _CHANNELS:
            tokens.pos -= 1
            raise tokens.error(
                f"unknown channel {channel!r} on joint {name}",
                "channels are Xposition Yposition Zposition Xrotation Yrotation Zrotation",
            )
        if channel in joint.channels:
            tokens.pos -= 1
            raise tokens.error(
                f"channel {channel} appears twice on joint {name}",
                "each of the six channels may appear once per joint",
            )
        joint.channels.append(channel)


def _parse_hierarchy(tokens: _Tokens, root: str, root_line: int) -> list[_RawJoint]:
    """The joints, parents before children, depth first.

    Iterative (a stack of open joints), so depth costs no recursion.
    """
    joints: list[_RawJoint] = []
    _open_joint(tokens, root, -1, root_line, joints)
    open_joints = [0]
    while open_joints:
        index = open_joints[-1]
        joint = joints[index]
        token, line = tokens.next("JOINT, End Site or '}' closing a joint")
        if token == "}":
            open_joints.pop()
        elif token == "JOINT":
            child, line = tokens.next("a joint name")
            _open_joint(tokens, child, index, line, joints)
            open_joints.append(len(joints) - 1)
        elif token == "End":
            tokens.expect("Site")
            tokens.expect("{")
            joint.end_site_line = tokens.expect("OFFSET")
            joint.end_site = [tokens.number("End Site OFFSET", joint.name) for _ in range(3)]
            tokens.expect("}")
        else:
            tokens.pos -= 1
            raise tokens.error(
                f"unexpected {token!r} in joint {joint.name}", "expected JOINT, End Site or '}'"
            )
    return joints


def _parse_header(path: str, lines: list[str], start: int) -> tuple[int, float, float, int, int]:
    """Frames and Frame Time after MOTION.

    Returns (frames, frame_time, fps, index of the first data line, line number of Frames:).
    """
    values: dict[str, tuple[str, int]] = {}
    i = start
    for key, pattern in _HEADER:
        while i < len(lines) and not lines[i].strip():
            i += 1
        text = lines[i].strip() if i < len(lines) else ""
        match = pattern.fullmatch(text)
        if not match:
            raise MotionFileError(
                path, i + 1, f"expected '{key} ...' after MOTION, found {text[:40]!r}"
            )
        values[key] = (match.group(1).strip(), i + 1)
        i += 1
    frames_text, frames_line = values["Frames:"]
    time_text, time_line = values["Frame Time:"]
    try:
        frames = int(frames_text)
    except ValueError:
        raise MotionFileError(
            path, frames_line, f"frame count {frames_text!r} is not a whole number"
        ) from None
    try:
        frame_time = float(time_text)
    except ValueError:
        raise MotionFileError(
            path, time_line, f"frame time {time_text!r} is not a number"
        ) from None
    if frames <= 0:
        raise MotionFileError(
            path,
            frames_line,
            f"the file declares {frames} frames",
            "a clip needs at least one frame",
        )
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise MotionFileError(
            path, time_line, f"frame time {time_text} must be a positive number of seconds"
        )
    fps = _rate(frame_time)
    if not fps_in_range(fps):
        rate = 1.0 / frame_time
        rate_text = f"{rate:.6g} fps" if np.isfinite(rate) else "more than 1e308 fps"
        raise MotionFileError(
            path,
            time_line,
            f"frame time {time_text} s is {rate_text}, outside the accepted {FPS_RANGE_TEXT}",
            "Frame Time is seconds per frame, e.g. 0.0333333 for 30 fps",
        )
    return frames, frame_time, fps, i, frames_line


def _scan_for_bad_line(path: str, rows: list[tuple[int, str]], n_channels: int) -> MotionFileError:
    """Slow path, taken only when the fast parse failed: find the first offending line."""
    for k, (line, text) in enumerate(rows):
        words = text.split()
        if len(words) != n_channels:
            return MotionFileError(
                path,
                line,
                f"frame {k + 1} has {len(words)} values, "
                f"the hierarchy declares {n_channels} channels",
                "the line is cut short or has extra values",
            )
        for column, word in enumerate(words, start=1):
            try:
                value = float(word)
            except ValueError:
                return MotionFileError(
                    path, line, f"value {column} of frame {k + 1} is {word!r}, not a number"
                )
            if not np.isfinite(value):
                return MotionFileError(
                    path, line, f"value {column} of frame {k + 1} is {word}, not finite"
                )
    return MotionFileError(path, rows[0][0] if rows else None, "motion data could not be read")


def _read_motion_block(
    path: str, lines: list[str], first: int, frames: int, frames_line: int, n_channels: int
) -> tuple[np.ndarray, list[int]]:
    """The frame lines after the header (blank lines skipped) as a (frames, channels) array, and
    the line number of each frame."""
    rows = [
        (number, text) for number, text in enumerate(lines[first:], start=first + 1) if text.strip()
    ]
    if len(rows) != frames:
        raise MotionFileError(
            path,
            frames_line,
            f"the header declares {frames} frames but {len(rows)} frame lines follow",
            "fix the 'Frames:' line or restore the missing frames",
        )
    numbers = [number for number, _ in rows]
    if n_channels == 0:
        return np.zeros((frames, 0)), numbers
    try:
        data = np.loadtxt([text for _, text in rows], dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        raise _scan_for_bad_line(path, rows, n_channels) from None
    if data.shape != (frames, n_channels) or not np.all(np.isfinite(data)):
        raise _scan_for_bad_line(path, rows, n_channels)
    return data, numbers


def read_bvh(path: str, units: str | float = "auto") -> Motion:
    """Parse a BVH file into a Motion (metres, unit quaternions). Raises MotionFileError."""
    with open(path, "rb") as f:
        return parse_bvh(f.read(), path, units)


def parse_bvh(
    raw: bytes, path: str, units: str | float = "auto", stored_as: str | None = None
) -> Motion:
    """A BVH file's bytes into a Motion; `path` names it in errors, `stored_as` in the catalogue
    (default: its absolute path). Raises MotionFileError."""
    lines = lines_of(raw)
    tokens = _Tokens(path, lines)
    if not tokens.items:
        raise MotionFileError(
            path, 1, "the file is empty", "expected a BVH file starting with HIERARCHY"
        )
    tokens.expect("HIERARCHY")
    tokens.expect("ROOT")
    root_name, root_line = tokens.next("the root joint's name")
    raw_joints = _parse_hierarchy(tokens, root_name, root_line)
    if tokens.pos != len(tokens.items):
        raise tokens.error(
            f"unexpected {tokens.items[tokens.pos][0]!r} after the hierarchy", "expected MOTION"
        )
    if not tokens.motion_line:
        raise MotionFileError(
            path, len(lines), "no MOTION section", "the file is truncated or holds only a skeleton"
        )
    names = [j.name for j in raw_joints]
    seen: dict[str, int] = {}
    for j in raw_joints:
        if j.name in seen:
            raise MotionFileError(
                path,
                j.line,
                f"joint name {j.name!r} is used twice (first on line {seen[j.name]})",
                "every joint needs its own name",
            )
        seen[j.name] = j.line
    for j in raw_joints:
        order = "".join(c[0] for c in j.channels if c.endswith("rotation"))
        if order and not quaternion.is_supported_order(order):
            raise MotionFileError(
                path, j.line, f"rotation order {order} of {j.name} is not supported"
            )

    frames, frame_time, fps, first_data, frames_line = _parse_header(
        path, lines, tokens.motion_line
    )
    n_channels = sum(len(j.channels) for j in raw_joints)
    data, frame_lines = _read_motion_block(path, lines, first_data, frames, frames_line, n_channels)

    joint_map = guess_joint_map(names, [j.parent for j in raw_joints])
    # Offsets near the float limit may sum to inf: the units rule refuses that figure's size.
    with np.errstate(over="ignore", invalid="ignore"):
        rest_points = _rest_points(raw_joints, names.index(joint_map.get("pelvis", root_name)))
        try:
            unit_m, rule = resolve_units(units, rest_points)
        except UnitsError as e:
            raise MotionFileError(path, None, str(e)) from None
    _check_lengths(path, raw_joints, data, frame_lines, unit_m)

    joints: list[Joint] = []
    rotations = np.empty((frames, len(raw_joints), 4))
    rotations[:] = (1.0, 0.0, 0.0, 0.0)
    translated: list[int] = []
    position_columns: list[
        list[int]
    ] = []  # per translated joint: data column per axis, -1 keeps the offset
    by_order: dict[
        str, tuple[list[int], list[list[int]]]
    ] = {}  # one vectorised conversion per order
    column = 0
    for k, j in enumerate(raw_joints):
        cols = {c: column + i for i, c in enumerate(j.channels)}
        column += len(j.channels)
        order = "".join(c[0] for c in j.channels if c.endswith("rotation"))
        if order:
            group = by_order.setdefault(order, ([], []))
            group[0].append(k)
            group[1].append([cols[a + "rotation"] for a in order])
        if any(c.endswith("position") for c in j.channels):
            translated.append(k)
            position_columns.append([cols.get(a + "position", -1) for a in "XYZ"])
        joints.append(
            Joint(
                name=j.name,
                parent=j.parent,
                offset=tuple(float(v) * unit_m for v in j.offset),
                channels=tuple(j.channels),
                rotation_order=order,
                end_site=None
                if j.end_site is None
                else tuple(float(v) * unit_m for v in j.end_site),
            )
        )
    for order, (members, columns) in by_order.items():
        rotations[:, members] = quaternion.from_euler(np.radians(data[:, columns]), order)

    skeleton = Skeleton(
        joints=joints,
        unit_m=unit_m,
        source_format="bvh",
        joint_map=joint_map,
        mirror_pairs=guess_mirror_pairs(names),
        name=os.path.splitext(os.path.basename(path))[0],
    )
    translations_array = np.zeros((frames, len(translated), 3))
    if translated:
        columns = np.array(position_columns)
        offsets = np.array([raw_joints[k].offset for k in translated])
        translations_array[:] = offsets  # position channels a joint lacks keep its offset
        present = columns >= 0
        translations_array[:, present] = data[:, columns[present]]
        translations_array *= unit_m
    return Motion(
        skeleton=skeleton,
        rotations=rotations,
        translations=translations_array,
        fps=fps,
        name=os.path.splitext(os.path.basename(path))[0],
        source=Source(
            path=stored_as or os.path.abspath(path),
            sha256=hashlib.sha256(raw).hexdigest(),
            units_rule=rule,
        ),
        meta={"frame_time": frame_time},
    )


def _rate(frame_time: float) -> float:
    """Frames per second, snapped to a whole rate when within 0.1% of one.

    A Frame Time of '.0083333' or '0.008333' s means 120 fps.
    """
    fps = 1.0 / frame_time
    if not np.isfinite(fps):  # a subnormal frame time: refused as out of range
        return fps
    whole = round(fps)
    return float(whole) if whole > 0 and abs(fps - whole) <= 1e-3 * whole else round(fps, 3)


def _check_lengths(
    path: str, joints: list[_RawJoint], data: np.ndarray, frame_lines: list[int], unit_m: float
) -> None:
    """Refuse offsets, End Sites and positions beyond MAX_LENGTH_M, naming their line."""
    limit = MAX_LENGTH_M / unit_m  # in file units
    hint = "the value is damaged, or the units are wrong: see --units"

    def refuse(line: int, what: str, value: float) -> MotionFileError:
        return MotionFileError(
            path,
            line,
            f"{what} is {value:g} units = {abs(value) * unit_m:.4g} m, "
            f"beyond the {MAX_LENGTH_M:,g} m accepted",
            hint,
        )

    for j in joints:
        for what, values, line in (
            (f"{j.name} OFFSET", j.offset, j.offset_line),
            (f"{j.name} End Site OFFSET", j.end_site or (), j.end_site_line),
        ):
            big = [v for v in values if not abs(v) <= limit]
            if big:
                raise refuse(line, what, big[0])
    columns = [c for c, name in enumerate(_column_names(joints)) if name.endswith("position")]
    if columns:
        positions = data[:, columns]
        bad = np.argwhere(~(np.abs(positions) <= limit))
        if len(bad):
            row, column = bad[0]
            value = float(positions[row, column])
            raise refuse(
                frame_lines[row],
                f"value {columns[column] + 1} of frame {row + 1} (a position)",
                value,
            )


def _column_names(joints: list[_RawJoint]) -> list[str]:
    """The channel of each motion column, in file order."""
    return [c for j in joints for c in j.channels]


def _rest_points(joints: list[_RawJoint], top: int) -> np.ndarray:
    """Rest-pose positions (file units) of the joints and End Sites below `top` (at the origin).

    The units rule measures the body from the pelvis down its subtree: a top
    joint's offset to the pelvis can be a displacement (Bandai stores the first
    frame's travel, up to metres, in the Hips offset), not a body dimension.
    """
    positions: dict[int, np.ndarray] = {top: np.zeros(3)}
    points: list[np.ndarray] = [positions[top]]
    for k, j in enumerate(joints):
        if k != top and j.parent in positions:
            positions[k] = positions[j.parent] + np.array(j.offset)
            points.append(positions[k])
        if k in positions and j.end_site is not None:
            points.append(positions[k] + np.array(j.end_site))
    return np.array(points)
