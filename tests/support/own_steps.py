"""The tests' own foot contacts and steps (an implementation apart from the kernel's steps.py):
forward kinematics by scipy's rotations (own_kinematics), speeds by numpy's gradient, runs cleaned
on their lengths. The oracle of test_steps and test_primitives."""

from __future__ import annotations

import itertools

import numpy as np

from support import own_kinematics

SIDES = ("left", "right")


def own_positions(motion, joints):
    """World positions (frames, 3) of the named joints, by scipy's rotations."""
    sk = motion.skeleton
    positions = own_kinematics.world_positions(
        sk.parents, sk.offsets, sk.translated, motion.rotations, motion.translations
    )
    return {name: positions[:, sk.names.index(sk.joint_map[name])] for name in joints}


def own_cleanup(flags, fps):
    """Short gaps (under 0.1 s) filled, then short contacts (under 0.05 s) dropped, runs at the
    clip's ends left as they are: on run lengths."""
    runs = [(value, len(list(group))) for value, group in itertools.groupby(flags)]
    for flipped, shortest in ((False, 0.1), (True, 0.05)):
        out = [
            (not value if value == flipped and 0 < k < len(runs) - 1 and n / fps < shortest
             else value, n)
            for k, (value, n) in enumerate(runs)
        ]  # fmt: skip
        runs = [(v, sum(n for _, n in g)) for v, g in itertools.groupby(out, key=lambda r: r[0])]
    return np.concatenate([np.full(n, value) for value, n in runs])


def own_contacts(motion):
    sk = motion.skeleton
    names = [f"{s}_{p}" for s in SIDES for p in ("ankle", "toe")]
    positions = own_positions(motion, names)
    offsets, index = sk.offsets, sk.names
    leg = np.mean([
        np.linalg.norm(offsets[index.index(sk.joint_map[f"{s}_knee"])])
        + np.linalg.norm(offsets[index.index(sk.joint_map[f"{s}_ankle"])])
        for s in SIDES
    ])  # fmt: skip
    low = {s: np.minimum(positions[f"{s}_ankle"][:, 1], positions[f"{s}_toe"][:, 1]) for s in SIDES}
    ground = np.percentile(np.concatenate(list(low.values())), 5)
    contacts = {}
    for s in SIDES:
        speed = np.minimum(
            *(np.linalg.norm(np.gradient(positions[f"{s}_{p}"], 1 / motion.fps, axis=0), axis=1)
              for p in ("ankle", "toe"))
        )  # fmt: skip
        raw = (speed < 0.5 * leg) & (low[s] < ground + 0.1 * leg)
        contacts[s] = own_cleanup(raw.tolist(), motion.fps)
    return contacts


def own_touchdowns(contact):
    return [f for f in range(1, len(contact)) if contact[f] and not contact[f - 1]]


def own_steps(contacts, fps):
    """Between each touchdown of one foot and the other's: from the latest touchdown of the planted
    foot since the other's last that leaves 0.2 to 1.5 s."""
    events = sorted((f, s) for s in SIDES for f in own_touchdowns(contacts[s]))
    out = []
    for k, (end, landed) in enumerate(events):
        if k == 0 or events[k - 1][1] == landed:
            continue
        back = k - 1
        while back >= 0 and events[back][1] != landed:
            if 0.2 <= (end - events[back][0]) / fps <= 1.5:
                out.append((f"{landed}_step", events[back][0], end))
                break
            back -= 1
    return out
