"""A simulation's ground truth in a run's log: the topics and how they are read.

The simulator writes its truth beside the devices' readings (:mod:`twin.sim.rig` records
it as it happens); the campaign's records never depend on it, and results read it, where
a log has it, to compare the estimates with the truth. A real run's log has none.

- :data:`TRUTH_CAMERA`: ``{"name", "camera"}``, each camera's true model in W
  (:func:`calib.io.camera_files.camera_to_dict`), at the start.
- :data:`TRUTH_INSTRUMENT`: ``{"timestamp", "translation", "yaw"}``, the total station's
  true centre in W, m, and heading, rad, at the start and whenever the parent's pose
  estimate is set from a fix.
- :data:`TRUTH_ROBOT`: ``{"robot", "timestamp", "translation", "rotation"}``, a robot's
  base body in W: its origin, m, and its (3, 3) body-to-W rotation, at the start and after
  each of its drives.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

TRUTH_CAMERA = "/truth/camera"
TRUTH_INSTRUMENT = "/truth/instrument"
TRUTH_ROBOT = "/truth/robot"


def instrument_truth(
    records: Iterable[Mapping[str, Any]], times: Iterable[float]
) -> list[NDArray[np.float64] | None]:
    """The instrument's true centre, (3,) m in W, at each of ``times`` (s): the latest
    :data:`TRUTH_INSTRUMENT` record at or before it (None where there is none).

    Args:
        records: the truth records' data, in any order.
        times: when the truth is wanted (e.g. each CPS fix's timestamp).
    """
    by_time = sorted(
        ((float(r["timestamp"]), np.asarray(r["translation"], dtype=float)) for r in records),
        key=lambda item: item[0],
    )
    stamps = [t for t, _ in by_time]
    out: list[NDArray[np.float64] | None] = []
    for t in times:
        k = bisect.bisect_right(stamps, float(t)) - 1
        out.append(by_time[k][1] if k >= 0 else None)
    return out
