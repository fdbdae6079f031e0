"""Filling a skeleton's joint map (standard names -> joints) and its left/right pairing.

Both are guesses from names that hold for Bandai, CMU ASF, CMU BVH conversions
and Mixamo-style rigs; they are stored editable in modb.skeletons.
"""

from __future__ import annotations

import re

# Ordered candidates per standard name, compared after normalising (lowercase,
# namespace prefix like 'mixamorig:' dropped, non-alphanumerics removed). The
# joint must sit at that anatomical joint and rotate there: for ASF that is the
# bone starting there (knee = ltibia), for BVH the joint itself (knee = LeftKnee).
_CANDIDATES = {
    "pelvis": ["hips", "pelvis", "root"],
    "spine": ["spine", "lowerback", "spine1"],
    "chest": ["thorax", "chest2", "chest", "upperback", "spine2"],
    "neck": ["lowerneck", "neck"],
    "head": ["head"],
    "hip": ["upperlegS", "Supleg", "Ship", "Sfemur", "Sthigh", "Supperleg"],
    "knee": ["lowerlegS", "Sleg", "Sknee", "Stibia", "Sshin", "Slowerleg"],
    "ankle": ["footS", "Sfoot", "Sankle"],
    "toe": ["toesS", "Stoebase", "Stoe", "Stoes"],
    "shoulder": ["upperarmS", "Sarm", "Shumerus", "Supperarm", "Sshoulder"],
    "elbow": ["lowerarmS", "Sforearm", "Selbow", "Sradius", "Slowerarm"],
    "wrist": ["handS", "Swrist", "Shand"],  # CMU's lhand/LeftWrist: the wrist is LeftWrist
}
_SIDE_WORDS = {"left": ("left", "l"), "right": ("right", "r")}


def _normalise(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.split(":")[-1].lower())


def _expand(pattern: str, side: str) -> list[str]:
    """'Sknee' -> ['leftknee', 'lknee']; 'kneeS' -> ['kneeleft', 'kneel'] (S marks the side)."""
    if "S" not in pattern:
        return [pattern]
    return [pattern.replace("S", word) for word in _SIDE_WORDS[side]]


def guess_joint_map(names: list[str]) -> dict[str, str]:
    by_norm: dict[str, str] = {}
    for n in names:
        by_norm.setdefault(_normalise(n), n)
    result: dict[str, str] = {}
    for key, patterns in _CANDIDATES.items():
        sides = ("left", "right") if any("S" in p for p in patterns) else (None,)
        for side in sides:
            standard = f"{side}_{key}" if side else key
            for pattern in patterns:
                hit = (
                    next((by_norm[c] for c in _expand(pattern, side) if c in by_norm), None)
                    if side
                    else by_norm.get(pattern)
                )
                if hit is not None:
                    result[standard] = hit
                    break
    return result


# (left, right) spellings, tried in order: suffixes first, then prefixes.
_SWAPS = (
    (re.compile(r"^(.*[_.\-])L$"), r"\1R"),
    (re.compile(r"^(.*[_.\-])l$"), r"\1r"),
    (re.compile(r"^Left(.*)$"), r"Right\1"),
    (re.compile(r"^left(.*)$"), r"right\1"),
    (re.compile(r"^(.*)Left$"), r"\1Right"),
    (re.compile(r"^(.*)_left$"), r"\1_right"),
    (re.compile(r"^L(.+)$"), r"R\1"),
    (re.compile(r"^l(.+)$"), r"r\1"),
)


def guess_mirror_pairs(names: list[str]) -> list[tuple[str, str]]:
    """Every (left, right) pair whose names differ only in a side marker."""
    present = set(names)
    pairs: list[tuple[str, str]] = []
    paired: set[str] = set()
    for name in names:
        if name in paired:
            continue
        prefix, _, base = name.rpartition(":")  # 'mixamorig:LeftArm': the side is in the base name
        for pattern, replacement in _SWAPS:
            if pattern.match(base):
                other = (prefix + ":" if prefix else "") + pattern.sub(replacement, base)
                if other in present and other != name and other not in paired:
                    pairs.append((name, other))
                    paired.update((name, other))
                    break
    return pairs
