"""The paper's measured numbers as targets of a Monte Carlo: each Table III entry and the
repeatability of cameras 1 and 2, beside the twin's distribution over trials.

A Table III entry (world or local, pixel or 3D, a visit of camera 1 or 2) is compared with
the trials' values of that visit; the repeatability of a camera with the norm of its second
calibrated centre minus its first, per trial (the paper gives one such difference per
camera, :data:`twin.report.paper.REPEATABILITY_MM`). The paper's numbers come from one run
of the real system: where they fall in the twin's distribution (their percentile) says more
than the ratio of medians, above all for the world entries, whose spread over trials is
wide.

Pure functions of the trial table's rows (:data:`twin.montecarlo.trial.COLUMNS`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.montecarlo.sources import ALL
from twin.report.paper import REPEATABILITY_MM, TABLE_III
from twin.report.reading import visit_name

LOCAL_BAND = 0.20
"""A local entry's twin median within this fraction of the paper's counts as matched."""

WORLD_BAND = 0.30
"""A world entry's twin median within this fraction of the paper's counts as matched (one
run's world errors are one draw of a wide distribution)."""

SPREAD = (10.0, 90.0)
"""The percentile range shown beside each median, and inside which the paper's
repeatability should fall."""

_METRICS = {
    ("world", "px"): "world_pixel_mean",
    ("world", "mm"): "world_error_3d_mean_mm",
    ("local", "px"): "local_pixel_mean",
    ("local", "mm"): "local_error_3d_mean_mm",
}


@dataclass(frozen=True)
class Target:
    """One number the paper measured.

    Attributes:
        camera: camera name in the twin. visit: the camera's visit (0 for a repeatability,
            which compares its last visit with its first).
        kind: ``world``, ``local`` or ``repeatability``. unit: ``px`` or ``mm``.
        paper: the paper's value, in ``unit``.
    """

    camera: str
    visit: int
    kind: str
    unit: str
    paper: float

    @property
    def name(self) -> str:
        """How tables and figures name it, e.g. ``cam1 (2nd) world px``."""
        if self.kind == "repeatability":
            return f"{self.camera} repeatability mm"
        return f"{visit_name((self.camera, self.visit))} {self.kind} {self.unit}"


def _table_iii_targets() -> tuple[Target, ...]:
    out = []
    for col in TABLE_III:
        for kind in ("local", "world"):
            for unit in ("px", "mm"):
                value = getattr(col, f"{kind}_pixel" if unit == "px" else f"{kind}_3d_mm")
                out.append(Target(col.camera, col.visit, kind, unit, float(value)))
    return tuple(out)


TARGETS: tuple[Target, ...] = _table_iii_targets() + tuple(
    Target(camera, 0, "repeatability", "mm", float(np.linalg.norm(d)))
    for camera, d in REPEATABILITY_MM.items()
)
"""The 16 Table III entries (local, then world, per visit in the paper's order) and the
two repeatabilities (norm of the published differences: 42.2 mm and 47.3 mm)."""


def applies(rows: Sequence[dict[str, Any]]) -> bool:
    """Whether the table's visits include every visit the paper measured (the paper's hall
    or a scenario with its cameras and visits)."""
    visits = {(r["camera"], r["visit"]) for r in rows}
    return all(col.key in visits for col in TABLE_III)


def _offsets(rows: Sequence[dict[str, Any]], camera: str) -> dict[int, list[NDArray]]:
    """Per trial, the camera's calibrated-minus-true centres (3,), mm, in visit order."""
    by: dict[int, list[tuple[int, NDArray]]] = {}
    for r in rows:
        if r["camera"] == camera and r["calibrated"]:
            d = np.array([r["position_dx_mm"], r["position_dy_mm"], r["position_dz_mm"]])
            if np.all(np.isfinite(d)):
                by.setdefault(int(r["trial"]), []).append((int(r["visit"]), d))
    return {t: [d for _, d in sorted(v, key=lambda x: x[0])] for t, v in by.items()}


def trial_values(rows: Sequence[dict[str, Any]], target: Target, config: str = ALL) -> NDArray:
    """(n,) the target's value in each trial of ``config`` that has it (finite values)."""
    mine = [r for r in rows if r["config"] == config]
    if target.kind == "repeatability":
        offsets = _offsets(mine, target.camera)
        values = [np.linalg.norm(v[-1] - v[0]) for v in offsets.values() if len(v) > 1]
    else:
        column = _METRICS[(target.kind, target.unit)]
        values = [
            r[column]
            for r in mine
            if r["camera"] == target.camera and r["visit"] == target.visit and r["calibrated"]
        ]
    a = np.asarray(values, dtype=float)
    return a[np.isfinite(a)]


def percentile_of(values: NDArray, value: float) -> float:
    """Where ``value`` falls among ``values``: the percentage of them below it (ties count
    half), NaN without values."""
    if len(values) == 0:
        return math.nan
    below = np.count_nonzero(values < value) + 0.5 * np.count_nonzero(values == value)
    return float(100.0 * below / len(values))


def matched(target: Target, median: float, p_low: float, p_high: float) -> bool:
    """Whether the twin matches the paper on ``target``: a local entry's median within
    :data:`LOCAL_BAND`, a world entry's within :data:`WORLD_BAND`, the repeatability inside
    the twin's :data:`SPREAD`."""
    if not math.isfinite(median):
        return False
    if target.kind == "repeatability":
        return p_low <= target.paper <= p_high
    band = LOCAL_BAND if target.kind == "local" else WORLD_BAND
    return abs(median / target.paper - 1.0) <= band


def against_paper(rows: Sequence[dict[str, Any]], config: str = ALL) -> list[dict[str, Any]]:
    """Every target beside the twin: the paper's value, the trials' median and
    :data:`SPREAD` percentiles, the paper's percentile among the trials, median / paper,
    and whether they match (:func:`matched`)."""
    out = []
    for target in TARGETS:
        v = trial_values(rows, target, config)
        if len(v):
            median, low, high = (float(x) for x in np.percentile(v, [50.0, *SPREAD]))
        else:
            median = low = high = math.nan
        out.append(
            {
                "name": target.name,
                "camera": target.camera,
                "visit": target.visit,
                "kind": target.kind,
                "unit": target.unit,
                "paper": target.paper,
                "n": len(v),
                "median": median,
                "p10": low,
                "p90": high,
                "paper_percentile": percentile_of(v, target.paper),
                "ratio": median / target.paper if len(v) else math.nan,
                "matched": matched(target, median, low, high),
            }
        )
    return out
