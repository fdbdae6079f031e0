"""The planner's paths (issue 60): the pelvis on the ground, seen from above, for single goals
behind the character and beside it, each walked from the start pose (pelvis above the origin, facing
+Z) by modb.synthesize_from_models, for one or more graphs of models; written as an SVG, and each
walk's time to its goal printed.

    .venv/bin/python bench/planner_paths.py OUT.svg DSN=GRAPH [DSN=GRAPH ...]
"""

import sys
from pathlib import Path

import numpy as np
import psycopg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "extension" / "plpython"))
from modb_kernel.step_search import Rig  # noqa: E402

GOALS = {"behind, 4 m": (0.0, -4.0), "behind and aside": (1.0, -3.5),
         "1.5 m to the right": (-1.5, 0.3), "1 m to the left": (1.0, 0.0)}  # fmt: skip
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")
SECONDS, SEED, RADIUS = 10.0, 1, 0.5
SCALE, PANEL, MARGIN = 60.0, 420, 30  # pixels per metre, panel width


def walk(dsn: str, graph: str, goal) -> tuple[np.ndarray, float, dict]:
    with psycopg.connect(dsn) as conn:
        fps, rotations, translations, report = conn.execute(
            "SELECT fps, rotations, translations, report FROM modb.synthesize_from_models("
            "%s, %s::float8[], %s, %s)", [graph, [list(goal)], SECONDS, SEED],
        ).fetchone()
        hierarchy, joint_map = conn.execute(
            "SELECT s.hierarchy, s.joint_map FROM modb.graphs g JOIN modb.skeletons s "
            "ON s.id = g.skeleton_id WHERE g.name = %s AND g.kind = 'models'", [graph]).fetchone()
    rig = Rig({"hierarchy": hierarchy, "joint_map": joint_map})
    p = rig.positions(np.asarray(rotations, float), np.asarray(translations, float))
    return p[:, rig.pelvis][:, [0, 2]], fps, report


def panel(x0: float, title: str, walks: list) -> list[str]:
    # +Z up the page, +X (the character's left) to the left: seen from above, behind it
    def at(point):
        return x0 + PANEL / 2 - SCALE * point[0], MARGIN + 60 + SCALE * (2.0 - point[1])

    out = [f'<text x="{x0 + 10}" y="{MARGIN}" font-size="14">{title}</text>']
    sx, sy = at((0.0, 0.0))
    out.append(f'<polygon points="{sx},{sy - 9} {sx - 5},{sy + 5} {sx + 5},{sy + 5}" fill="#333"/>')
    for (name, goal, path, line), colour in zip(walks, COLOURS):
        gx, gy = at(goal)
        out.append(f'<circle cx="{gx:.1f}" cy="{gy:.1f}" r="{SCALE * RADIUS:.1f}" fill="none" '
                   f'stroke="{colour}" stroke-dasharray="4 3"/>')  # fmt: skip
        points = " ".join(f"{a:.1f},{b:.1f}" for a, b in (at(q) for q in path[::2]))
        out.append(f'<polyline points="{points}" fill="none" stroke="{colour}" '
                   'stroke-width="1.5"/>')
    for k, (name, _, _, line) in enumerate(walks):
        out.append(f'<text x="{x0 + 10}" y="{MARGIN + 470 + 16 * k}" font-size="11" '
                   f'fill="{COLOURS[k]}">{name}: {line}</text>')  # fmt: skip
    return out


def main() -> None:
    out, pairs = Path(sys.argv[1]), [a.rsplit("=", 1) for a in sys.argv[2:]]
    body = []
    for k, (dsn, graph) in enumerate(pairs):
        walks = []
        for name, goal in GOALS.items():
            path, fps, report = walk(dsn, graph, goal)
            reached = report["reached"].get("1")
            distance = float(np.hypot(*goal))
            line = (f"{distance:.1f} m, reached in {reached / fps:.2f} s" if reached is not None
                    else f"not reached (closest {np.hypot(*(path - goal).T).min():.2f} m)")
            print(f"{graph}: {name} {goal}: {line}")
            walks.append((name, goal, path, line))
        body += panel(k * PANEL, f"graph {graph}", walks)
    width, height = PANEL * len(pairs), MARGIN + 540
    out.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
                   f'font-family="sans-serif"><rect width="100%" height="100%" fill="white"/>'
                   + "".join(body) + "</svg>\n")  # fmt: skip


if __name__ == "__main__":
    main()
