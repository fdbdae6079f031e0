"""A side view of the feet (issue 59): toe heights over time, as the test's own kinematics
(tests/support/feet_oracle.py, scipy's rotations) compute them, for a captured walk and for both
synthesis families with their stance feet held (the default) and without, written as an SVG.

    .venv/bin/python bench/feet_side_view.py DSN COLLECTION GRAPH_OF_MODELS docs/feet-side-view.svg

COLLECTION: the walks the snippets and the models came from (motion matching draws from it);
GRAPH_OF_MODELS: a graph of step models over it (modb model graph). The course, its seconds and the
window drawn are fixed below.
"""

import sys
from pathlib import Path

import numpy as np
import psycopg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.feet_oracle import Body, Capture  # noqa: E402

from modb.clips import read_motion  # noqa: E402
from modb.database import pgarray  # noqa: E402
from modb.synthesis.chain import Settings  # noqa: E402
from modb.synthesis.from_models import synthesize as synthesize_models  # noqa: E402
from modb.synthesis.synth import synthesize  # noqa: E402

COURSE = [(0.0, 6.0), (5.0, 8.0), (5.0, 2.0)]
SECONDS = 20.0
WINDOW = (6.0, 10.0)  # seconds of each strip drawn (walking, past the start)
WIDTH, PANEL, MARGIN = 760, 120, 40
TOP_CM = 25.0


def toes(body, motion):
    p = body.positions(motion.rotations, motion.translations)
    return p[:, body.toes, 1], motion.fps, p


def strips(conn, collection, graph):
    out = []
    for hold in (False, True):
        mm = synthesize(conn, COURSE, SECONDS, Settings(collection=collection, foot_hold=hold))
        out.append((f"motion matching, feet {'held' if hold else 'as the seams leave them'}",
                    mm.strip))  # fmt: skip
    for hold in ("off", "on"):
        conn.execute("SELECT set_config('modb.foot_hold', %s, false)", [hold])
        models = synthesize_models(conn, graph, COURSE, SECONDS)
        out.append((f"models, feet {'held' if hold == 'on' else 'as the seams leave them'}",
                    models.motion))  # fmt: skip
    conn.execute("RESET modb.foot_hold")
    return out


def panel(y0, title, heights, fps, capture, floor_cm):
    """One panel's SVG: the two toes' heights (cm) over the window, the capture's beside them."""
    first, last = (int(round(s * fps)) for s in WINDOW)
    span = last - first
    x = lambda k: MARGIN + (WIDTH - 2 * MARGIN) * k / span  # noqa: E731
    y = lambda cm: y0 + PANEL - PANEL * min(max(cm, -2.0), TOP_CM) / TOP_CM  # noqa: E731
    parts = [f'<text x="{MARGIN}" y="{y0 - 4}" font-size="12">{title}</text>',
             f'<rect x="{MARGIN}" y="{y0}" width="{WIDTH - 2 * MARGIN}" height="{PANEL}" '
             'fill="none" stroke="#ccc"/>',
             f'<line x1="{MARGIN}" x2="{WIDTH - MARGIN}" y1="{y(floor_cm):.1f}" '
             f'y2="{y(floor_cm):.1f}" stroke="#999" stroke-dasharray="4 3"/>']  # fmt: skip
    for series, colour, width in ((capture, "#bbb", 3), (heights, None, 1.5)):
        for side, c in zip(range(2), ("#1f77b4", "#d62728")):
            values = 100 * series[first:last, side]
            points = " ".join(f"{x(k):.1f},{y(v):.1f}" for k, v in enumerate(values))
            parts.append(f'<polyline points="{points}" fill="none" stroke="{colour or c}" '
                         f'stroke-width="{width}"/>')  # fmt: skip
    return parts


def main(dsn, collection, graph, out):
    with psycopg.connect(dsn, autocommit=True) as conn:
        pgarray.register(conn)
        rows = conn.execute(
            "SELECT c.clip_id, c.version FROM modb.current_clips c JOIN modb.clips k "
            "ON k.id = c.clip_id WHERE k.collection_id = ANY (modb.collection_subtree(%s)) "
            "ORDER BY 1", [collection]).fetchall()  # fmt: skip
        clips = [read_motion(conn, c, v) for c, v in rows]
        made = strips(conn, collection, graph)
    body = Body.of(clips[0].skeleton)
    capture = Capture.of(body, [(m.rotations, m.translations, m.fps) for m in clips])
    walk = max(clips, key=lambda m: m.n_frames)
    captured, _, _ = toes(body, walk)
    captured = np.concatenate([captured] * int(np.ceil(WINDOW[1] * walk.fps / len(captured)) + 1))
    height = len(made) * (PANEL + 30) + 60
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" '
           'font-family="sans-serif">',
           f'<text x="{MARGIN}" y="18" font-size="13">Toe heights, {WINDOW[0]:g}-{WINDOW[1]:g} s '
           f'(0-{TOP_CM:g} cm; blue left, red right; grey: a captured walk of {collection}; '
           "dashed: the capture's lowest toe)</text>"]  # fmt: skip
    for k, (title, motion) in enumerate(made):
        heights, fps, p = toes(body, motion)
        figures = capture.judge(body, p, fps)
        title += (f": sliding {figures['sliding_x']:.2f}x the capture's, lowest toe "
                  f"{figures['dip_cm']:.1f} cm below it, clearance {figures['clearance_x']:.2f}x")
        svg += panel(50 + k * (PANEL + 30), title, heights, fps, captured, 100 * capture.floor)
    svg.append("</svg>")
    Path(out).write_text("\n".join(svg) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:5])
