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
# Extra spellings tried after all of _CANDIDATES: CMU-style lToeJoint. (CMU's LHipJoint connects the
# pelvis to the hip: it is not the hip, LeftUpLeg is.)
_LATE_CANDIDATES = {"toe": ["Stoejoint"]}
_SIDED = ("hip", "knee", "ankle", "toe", "shoulder", "elbow", "wrist")


def _normalise(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.split(":")[-1].lower())


def _expand(pattern: str, side: str, flipped: bool = False) -> list[str]:
    """'Sknee' -> ['leftknee', 'lknee']; 'kneeS' -> ['kneeleft', 'kneel'] (S marks the side);
    flipped, the side word at the other end ('Sthigh' -> ['thighleft', 'thighl'], Blender's
    thigh.L)."""
    if "S" not in pattern:
        return [] if flipped else [pattern]
    if flipped:
        stem = pattern.replace("S", "")
        pattern = stem + "S" if pattern.startswith("S") else "S" + stem
    return [pattern.replace("S", word) for word in _SIDE_WORDS[side]]


def _by_name(names: list[str]) -> dict[str, str]:
    by_norm: dict[str, str] = {}
    for n in names:
        by_norm.setdefault(_normalise(n), n)
    result: dict[str, str] = {}
    # The names' usual spellings first; the side at the other end, then late ones, only for what
    # those leave out.
    for table, flipped in ((_CANDIDATES, False), (_CANDIDATES, True), (_LATE_CANDIDATES, False)):
        for key, patterns in table.items():
            sides = ("left", "right") if key in _SIDED else (None,)
            for side in sides:
                standard = f"{side}_{key}" if side else key
                if standard in result:
                    continue
                for pattern in patterns:
                    hit = next(
                        (
                            by_norm[c]
                            for c in _expand(pattern, side or "left", flipped)
                            if c in by_norm
                        ),
                        None,
                    )
                    if hit is not None:
                        result[standard] = hit
                        break
    return result


def _parent_indices(names: list[str], parents) -> list[int]:
    """Parents given as indices (-1: a root) or as names (None or '': a root)."""
    index = {n: k for k, n in enumerate(names)}
    out = []
    for p in parents:
        if isinstance(p, str) or p is None:
            out.append(index.get(p, -1) if p else -1)
        else:
            out.append(int(p))
    return out


def _chain(parents: list[int], k: int) -> list[int]:
    """k and its ancestors, k first."""
    out = [k]
    while parents[out[-1]] >= 0:
        out.append(parents[out[-1]])
    return out


def _common_ancestor(parents: list[int], a: int, b: int) -> int:
    above_a = _chain(parents, a)
    return next((k for k in _chain(parents, b) if k in above_a), -1)


def _depth_below(children: dict[int, list[int]], k: int) -> int:
    return 1 + max((_depth_below(children, c) for c in children.get(k, [])), default=0)


def _from_structure(names: list[str], parents: list[int], result: dict[str, str]) -> dict[str, str]:
    """Fill the standard joints names did not find: down each limb, then the trunk from where the
    legs and arms branch; returns standard name -> joint for each joint filled so."""
    at = {n: k for k, n in enumerate(names)}
    idx = {s: at[j] for s, j in result.items() if j in at}
    filled: dict[str, str] = {}

    def put(standard: str, k: int) -> None:
        idx[standard] = k
        result[standard] = names[k]
        filled[standard] = names[k]

    children: dict[int, list[int]] = {}
    for k, p in enumerate(parents):
        if p >= 0:
            children.setdefault(p, []).append(k)
    for side in ("left", "right"):  # down a limb: the only child, else the joint above stands in
        for chain in (("hip", "knee", "ankle", "toe"), ("shoulder", "elbow", "wrist")):
            for upper, lower in zip(chain, chain[1:]):
                above, standard = f"{side}_{upper}", f"{side}_{lower}"
                if standard in idx or above not in idx:
                    continue
                below = children.get(idx[above], [])
                free = len(below) == 1 and below[0] not in idx.values()
                put(standard, below[0] if free else idx[above])
    if "pelvis" not in idx and names:
        if "left_hip" in idx and "right_hip" in idx:
            k = _common_ancestor(parents, idx["left_hip"], idx["right_hip"])
            put("pelvis", max(k, 0))
        else:
            put("pelvis", 0)
    if "chest" not in idx and "left_shoulder" in idx and "right_shoulder" in idx:
        k = _common_ancestor(parents, idx["left_shoulder"], idx["right_shoulder"])
        if k >= 0:
            put("chest", k)
    if "chest" not in idx:
        return filled
    chest = idx["chest"]
    if "head" not in idx:  # the top of the chain above the chest: away from arms and legs
        limbs = {idx[s] for s in idx if s.endswith(_SIDED)}
        k = chest
        while True:
            up = [c for c in children.get(k, []) if not any(c in _chain(parents, j) for j in limbs)]
            if not up:
                break
            k = max(up, key=lambda c: _depth_below(children, c))
        put("head", k)
    above_head = _chain(parents, idx["head"])
    if "neck" not in idx:
        p = parents[idx["head"]]
        between = p >= 0 and p != chest and chest in _chain(parents, p)
        put("neck", p if between and chest in above_head else chest)
    if "spine" not in idx and "pelvis" in idx:
        path = _chain(parents, chest)
        if idx["pelvis"] in path:
            below = path[: path.index(idx["pelvis"])]  # chest first, the pelvis left out
            put("spine", below[-1] if below else chest)
    return filled


def explain_joint_map(names: list[str], parents) -> tuple[dict[str, str], dict[str, str]]:
    """The joint map, and the standard joints in it that came from the hierarchy rather than from
    names (standard name -> joint): a joint missing from the rig (no neck, no chest) is stood in for
    by the nearest one of its chain, which then serves two standard names."""
    result = _by_name(names)
    filled = _from_structure(names, _parent_indices(names, parents), result)
    return result, filled


def guess_joint_map(names: list[str], parents=None) -> dict[str, str]:
    """Standard name -> joint name: from names first, then (given parents, as indices or names)
    from the hierarchy for what names miss."""
    if parents is None:
        return _by_name(names)
    return explain_joint_map(names, parents)[0]


def describe_filled(skeleton: str, joint_map: dict[str, str], filled: dict[str, str]) -> str:
    """One line saying which standard joints came from the hierarchy ('' when none did); a joint
    already serving a standard name higher in the list (pelvis first) stands in for this one."""
    if not filled:
        return ""
    order = list(_CANDIDATES)
    rank = {s: order.index(s.split("_")[-1]) for s in joint_map}
    parts = []
    for standard in sorted(filled, key=rank.get):
        joint = filled[standard]
        if any(j == joint and rank[s] < rank[standard] for s, j in joint_map.items()):
            parts.append(f"no {standard} joint, {joint} stands in")
        else:
            parts.append(f"{standard} is {joint}")
    return (
        f"skeleton {skeleton}: joint map from the hierarchy where names did not say: "
        + "; ".join(parts)
        + " (joint map editable)"
    )


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
