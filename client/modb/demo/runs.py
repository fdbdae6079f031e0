"""Which clips of the demo's collection its family of motion models learns from, and what it does
with the runs beside the walks.

`modb annotate --steps` finds a run's strides as it finds a walk's (left_step, right_step: a
touchdown to the next, whatever the gait), so step models of a collection that holds both learn
both, and blend them: on Bandai dataset 2 (docs/models.md, "Runs and the family") such a family
walked the demo's course with quicker steps than any captured walk's, and its stance feet slid
nearly four times as much as those of the family of the walks alone. The demo therefore
annotates the walks and turns only; runs annotated before stay so (the demo deletes nothing),
and it says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import psycopg

from .data import is_run

# Per current clip of the collection (and those below it): whether `modb annotate --steps` marked
# segments of it, and how many steps it holds
CLIPS = """
SELECT c.clip_id, c.name,
       coalesce(bool_or((a.seg->>'auto')::boolean), false) AS annotated,
       count(a.seg) FILTER (WHERE a.seg->>'name' IN ('left_step', 'right_step')) AS steps
  FROM modb.current_clips c
  JOIN modb.clips k ON k.id = c.clip_id
  LEFT JOIN LATERAL jsonb_array_elements(coalesce(c.meta->'annotations', '[]')) AS a(seg) ON true
 WHERE k.collection_id = ANY (modb.collection_subtree(%s))
 GROUP BY c.clip_id, c.name
 ORDER BY c.clip_id
"""


@dataclass(frozen=True)
class StepClips:
    """The collection's clips as its family sees them."""

    walking: list[int]  # every clip but the runs: what the family learns from
    to_annotate: list[int]  # the walking clips `modb annotate --steps` has not marked yet
    runs: int  # how many runs the collection holds
    runs_annotated: int  # how many of them hold steps (annotated by hand or an earlier command)
    run_steps: int  # the steps those hold

    @classmethod
    def of(cls, conn: psycopg.Connection, collection: str) -> StepClips:
        rows = conn.execute(CLIPS, [collection]).fetchall()
        walking = [(clip, annotated) for clip, name, annotated, _ in rows if not is_run(name)]
        runs = [(annotated, steps) for _, name, annotated, steps in rows if is_run(name)]
        return cls(
            walking=[clip for clip, _ in walking],
            to_annotate=[clip for clip, annotated in walking if not annotated],
            runs=len(runs),
            runs_annotated=sum(steps > 0 for _, steps in runs),
            run_steps=sum(steps for _, steps in runs),
        )

    def runs_line(self, collection: str) -> str | None:
        """What the demo says of the runs (None: the collection holds none)."""
        if not self.runs:
            return None
        runs = f"{self.runs} run{'' if self.runs == 1 else 's'}"
        if self.runs_annotated:
            return (
                f"runs: {self.runs_annotated} of the {runs} of {collection} hold "
                f"{self.run_steps} steps (annotated before): the step models learn them beside the "
                'walks\' and blend the two gaits (docs/models.md, "Runs and the family")'
            )
        return (
            f"runs: the {runs} of {collection} {'is' if self.runs == 1 else 'are'} left out of the "
            "family: `modb annotate --steps` finds a run's strides as left and right steps, as it "
            "does a walk's, and models learning both blend the gaits into quicker, sliding steps "
            '(docs/models.md, "Runs and the family"); motion matching draws on them as on any clip'
        )
