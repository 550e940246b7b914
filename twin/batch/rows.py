"""Trials of one batch that each take their own steps: many campaigns of a site, each with
its own moves, executed together (the environment's vector runs its episodes so).

:func:`execute_rows` takes, for some rows of a :class:`twin.batch.execute.BatchRun`, the
steps each takes next, and runs them in lock step: at each round every row's next step,
rows whose steps are of one kind at once:

- the drives of one robot (each row's own stop), the placements of one child, the fixes
  from the same children: whatever the rows' moves;
- a data set's steps (its points, its end, its calibration), for the rows that take the
  same steps (the same tuple) only: a data set's stops must all be taken by the same rows.

A trial gives what it gives alone (see :class:`twin.batch.execute.BatchRun`), whatever
rows it runs with.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence

from twin.batch.execute import BatchRun
from twin.batch.steps import Calibrate, DataSetDone, Drive, Fix, Place, Point, Step

__all__ = ["execute_rows"]


def _kind(step: Step, steps: Sequence[Step], i: int) -> Hashable:
    """What steps run together must share (a drive's stop may differ by row); ``step`` is
    ``steps[i]``."""
    if isinstance(step, Drive):
        return ("drive", step.robot)
    if isinstance(step, Place):
        return ("place", step.child)
    if isinstance(step, Fix):
        return ("fix", step.children)
    if isinstance(step, (Point, DataSetDone, Calibrate)):
        return ("data", id(steps), i)
    raise TypeError(f"unknown step {step!r}")


def execute_rows(batch: BatchRun, work: Mapping[int, Sequence[Step]]) -> None:
    """Run each row's steps (row -> its steps, in order) on ``batch`` (see the module)."""
    at = {row: 0 for row, steps in work.items() if steps}
    while at:
        kinds: dict[Hashable, list[int]] = {}
        for row, i in at.items():
            kinds.setdefault(_kind(work[row][i], work[row], i), []).append(row)
        for rows in kinds.values():
            steps = [work[row][at[row]] for row in rows]
            if isinstance(steps[0], Drive) and any(s is not steps[0] for s in steps):
                batch.drive_rows(steps, rows)  # type: ignore[arg-type]
            else:
                batch.step(steps[0], rows)
        for row in list(at):
            at[row] += 1
            if at[row] == len(work[row]):
                del at[row]
