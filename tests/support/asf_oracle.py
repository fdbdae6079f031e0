"""A second ASF/AMC forward kinematics, written independently of modb.loader: own parsing, scipy
rotations.

Follows the Acclaim convention directly on bone tips: L = C M C^-1 with C from the bone's `axis` and
M from the AMC values (extrinsic, first dof first), world rotation R = R_parent L, tip = parent tip
+ R (direction * length)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def parse_asf(path):
    bones, hierarchy, root = {}, {}, {"order": [], "axis": "XYZ", "orientation": [0, 0, 0]}
    length, degrees = 1.0, True
    section, current = None, None
    for raw in open(path, encoding="latin-1"):
        w = raw.split()
        if not w or w[0].startswith("#"):
            continue
        if w[0].startswith(":"):
            section = w[0]
            continue
        if section == ":units" and w[0] == "length":
            length = float(w[1])
        elif section == ":units" and w[0] == "angle":
            degrees = w[1] == "deg"
        elif section == ":root" and w[0] == "order":
            root["order"] = w[1:]
        elif section == ":root" and w[0] == "axis":
            root["axis"] = w[1]
        elif section == ":root" and w[0] == "orientation":
            root["orientation"] = [float(x) for x in w[1:4]]
        elif section == ":bonedata":
            if w[0] == "begin":
                current = {"dof": []}
            elif w[0] == "end":
                bones[current["name"]] = current
            elif w[0] == "name":
                current["name"] = w[1]
            elif w[0] == "direction":
                current["direction"] = np.array([float(x) for x in w[1:4]])
            elif w[0] == "length":
                current["length"] = float(w[1])
            elif w[0] == "axis":
                current["axis"] = ([float(x) for x in w[1:4]], w[4])
            elif w[0] == "dof":
                current["dof"] = w[1:]
        elif section == ":hierarchy" and w[0] not in ("begin", "end"):
            for child in w[1:]:
                hierarchy[child] = w[0]
    return {
        "bones": bones,
        "parent": hierarchy,
        "root": root,
        "unit_m": 0.0254 / length,
        "degrees": degrees,
    }


def parse_amc(path):
    frames = []
    for raw in open(path, encoding="latin-1"):
        w = raw.split()
        if not w or w[0].startswith("#") or w[0].startswith(":"):
            continue
        if len(w) == 1 and w[0].isdigit():
            frames.append({})
        else:
            frames[-1][w[0]] = [float(x) for x in w[1:]]
    return frames


def bone_tips(asf, frames):
    """{bone: (frames, 3) tip positions in metres}, plus 'root': the root position."""
    deg = asf["degrees"]
    order = asf["root"]["order"]
    root_c = Rotation.from_euler(
        asf["root"]["axis"].lower(), asf["root"]["orientation"], degrees=deg
    )
    tips = {}
    world = {}
    values = np.array([f["root"] for f in frames])
    t = values[:, [order.index(c) for c in ("TX", "TY", "TZ")]]
    rot_cols = [c for c in order if c.startswith("R")]
    m = Rotation.from_euler(
        "".join(c[1].lower() for c in rot_cols),
        values[:, [order.index(c) for c in rot_cols]],
        degrees=deg,
    )
    world["root"] = root_c * m * root_c.inv()
    tips["root"] = t * asf["unit_m"]
    pending = list(asf["parent"].items())
    while pending:
        rest = []
        for bone, parent in pending:
            if parent not in world:
                rest.append((bone, parent))
                continue
            b = asf["bones"][bone]
            c = Rotation.from_euler(b["axis"][1].lower(), b["axis"][0], degrees=deg)
            if b["dof"]:
                angles = np.array([f[bone] for f in frames])
                local = (
                    c
                    * Rotation.from_euler("".join(d[1] for d in b["dof"]), angles, degrees=deg)
                    * c.inv()
                )
            else:
                local = Rotation.identity(len(frames))
            world[bone] = world[parent] * local
            tips[bone] = tips[parent] + world[bone].apply(
                b["direction"] * b["length"] * asf["unit_m"]
            )
        pending = rest
    return tips, asf["parent"]
