"""What a trial table says: error distributions per camera visit, the error budget by
noise source, and the Monte-Carlo spread beside the covariance propagation's prediction.

Pure functions of the table's rows (:data:`twin.montecarlo.trial.COLUMNS`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from twin.montecarlo.paper_targets import against_paper, applies
from twin.montecarlo.sources import ALL, SOURCES

PERCENTILES = (50.0, 90.0, 99.0)

METRICS = (
    "position_error_mm",
    "rotation_error_deg",
    "world_pixel_mean",
    "world_error_3d_mean_mm",
    "local_pixel_mean",
    "local_error_3d_mean_mm",
)
"""The per-visit quantities whose distribution is summarised."""

AGREEMENT = (0.8, 1.25)
"""Monte-Carlo RMS / predicted RMS within this range counts as agreement."""


def _finite(values: Sequence[float]) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    return a[np.isfinite(a)]


def _rms(a: np.ndarray) -> float:
    """Root mean square of ``a``, NaN when it is empty."""
    return float(np.sqrt(np.mean(a**2))) if len(a) else math.nan


def distribution(values: Sequence[float]) -> dict[str, float | int]:
    """Median, 90th and 99th percentile, mean, RMS and count of the finite values."""
    a = _finite(values)
    if len(a) == 0:
        return {
            "n": 0,
            "median": math.nan,
            "p90": math.nan,
            "p99": math.nan,
            "mean": math.nan,
            "rms": math.nan,
        }
    p = np.percentile(a, PERCENTILES)
    return {
        "n": len(a),
        "median": float(p[0]),
        "p90": float(p[1]),
        "p99": float(p[2]),
        "mean": float(a.mean()),
        "rms": _rms(a),
    }


def visits_of(rows: Sequence[dict[str, Any]]) -> list[tuple[str, int]]:
    """(camera, visit) in the order of the table's first trial."""
    return list(dict.fromkeys((r["camera"], r["visit"]) for r in rows))


def _select(rows: Sequence[dict], config: str, visit: tuple[str, int] | None = None) -> list:
    return [
        r
        for r in rows
        if r["config"] == config and (visit is None or (r["camera"], r["visit"]) == visit)
    ]


def visit_summary(rows: Sequence[dict[str, Any]], config: str = ALL) -> list[dict[str, Any]]:
    """Per camera visit of ``config``: the distributions of :data:`METRICS`, the share of
    trials that calibrated it, the distance travelled, and the predicted RMS position
    error beside the Monte-Carlo one."""
    out = []
    for visit in visits_of(rows):
        mine = _select(rows, config, visit)
        made = [r for r in mine if r["calibrated"]]
        transfer = _rms(_finite([r["predicted_transfer_rms_mm"] for r in made]))
        own = _rms(_finite([r["predicted_calibration_rms_mm"] for r in made]))
        predicted = math.hypot(transfer, own)
        mc = distribution([r["position_error_mm"] for r in made])
        ratio = mc["rms"] / predicted if predicted > 0 else math.nan
        entry: dict[str, Any] = {
            "camera": visit[0],
            "visit": visit[1],
            "trials": len(mine),
            "calibrated_fraction": len(made) / len(mine) if mine else math.nan,
            "distance_travelled_m": distribution([r["distance_travelled_m"] for r in made]),
            **{m: distribution([r[m] for r in made]) for m in METRICS},
            "predicted": {
                "transfer_rms_mm": transfer,
                "calibration_rms_mm": own,
                "rms_mm": predicted,
                "mc_over_predicted": ratio,
                "agrees": bool(AGREEMENT[0] <= ratio <= AGREEMENT[1]),
            },
        }
        adjusted = adjusted_summary(made)
        if adjusted is not None:
            entry["adjusted"] = adjusted
        out.append(entry)
    return out


def adjusted_summary(made: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """The global adjustment's errors of a visit's calibrated rows: the distribution of its
    position error, its Monte-Carlo RMS against the RMS of its predicted errors, and its
    centre's spread (the offset from the truth, mm) per axis; None without adjusted rows."""
    err = [r.get("adjusted_position_error_mm", math.nan) for r in made]
    if not len(_finite(err)):
        return None
    predicted = _rms(_finite([r["adjusted_predicted_rms_mm"] for r in made]))
    mc = distribution(err)
    ratio = mc["rms"] / predicted if predicted > 0 else math.nan
    return {
        "position_error_mm": mc,
        "rotation_error_deg": distribution([r["adjusted_rotation_error_deg"] for r in made]),
        "predicted_rms_mm": predicted,
        "mc_over_predicted": ratio,
        "agrees": bool(AGREEMENT[0] <= ratio <= AGREEMENT[1]),
    }


def parent_summary(rows: Sequence[dict[str, Any]], config: str = ALL) -> dict[str, Any]:
    """The parent's final position: Monte-Carlo spread per axis against the predicted
    standard deviation (RMS over trials of each trial's prediction), mm."""
    first = {}
    for r in _select(rows, config):
        first.setdefault(r["trial"], r)
    trials = list(first.values())
    out: dict[str, Any] = {"trials": len(trials)}
    if not trials:
        return out
    dist = _finite([r["parent_distance_m"] for r in trials])
    out["distance_travelled_m"] = float(np.median(dist)) if len(dist) else math.nan
    for axis in ("x", "y", "z"):
        err = _finite([r[f"parent_final_d{axis}_mm"] for r in trials])
        pred = _finite([r[f"parent_predicted_s{axis}_mm"] for r in trials])
        mc = float(np.std(err, ddof=1)) if len(err) > 1 else math.nan
        p = _rms(pred)
        out[axis] = {
            "mc_std_mm": mc,
            "mc_mean_mm": float(err.mean()) if len(err) else math.nan,
            "predicted_std_mm": p,
            "mc_over_predicted": mc / p if p > 0 else math.nan,
        }
    err3 = np.array([[r[f"parent_final_d{a}_mm"] for a in "xyz"] for r in trials], dtype=float)
    pred3 = np.array([[r[f"parent_predicted_s{a}_mm"] for a in "xyz"] for r in trials], float)
    ok = np.all(np.isfinite(err3), axis=1) & np.all(np.isfinite(pred3), axis=1)
    if ok.any():
        mc_rms = float(np.sqrt(np.mean(np.sum(err3[ok] ** 2, axis=1))))
        p_rms = float(np.sqrt(np.mean(np.sum(pred3[ok] ** 2, axis=1))))
        out["rms_3d"] = {
            "mc_mm": mc_rms,
            "predicted_mm": p_rms,
            # A parent that never moved has no predicted spread: no ratio.
            "mc_over_predicted": mc_rms / p_rms if p_rms > 0 else None,
        }
    return out


def budget(rows: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """The error budget: each source's share of the world-frame camera position error.

    A source's contribution is the mean squared position error with that source alone;
    its share is that over the sum of all sources' contributions. ``sum_over_all`` compares
    that sum with the mean square of the run with every source: near 1 when the sources
    add up independently. Returns None when the table has no one-source runs.
    """
    sources = [s for s in SOURCES if any(r["config"] == s for r in rows)]
    if not sources:
        return None

    def ms(config: str, visit: tuple[str, int] | None) -> float:
        err = _finite([r["position_error_mm"] for r in _select(rows, config, visit)])
        return float(np.mean(err**2)) if len(err) else math.nan

    out: dict[str, Any] = {"sources": sources, "visits": []}
    for visit in [*visits_of(rows), None]:
        parts = {s: ms(s, visit) for s in sources}
        total = sum(v for v in parts.values() if math.isfinite(v))
        everything = ms(ALL, visit)
        entry = {
            "rms_mm": {s: math.sqrt(v) if math.isfinite(v) else math.nan for s, v in parts.items()},
            "share": {s: v / total if total > 0 else math.nan for s, v in parts.items()},
            "all_rms_mm": math.sqrt(everything) if math.isfinite(everything) else math.nan,
            "sum_over_all": total / everything if everything > 0 else math.nan,
        }
        if visit is None:
            out["overall"] = entry
        else:
            out["visits"].append({"camera": visit[0], "visit": visit[1], **entry})
    return out


def failure_summary(rows: Sequence[dict[str, Any]], config: str = ALL) -> dict[str, Any]:
    """What went wrong in the trials of ``config``: ``kinds``, each failure kind's count over
    all trials (from ``failure_kinds``); ``trials_with_failures``; and ``not_calibrated``,
    the visits that gave no calibration, counted by reason (the ``not_calibrated`` text
    before its first colon), most frequent first."""
    trials: dict[int, str] = {}
    reasons: dict[str, int] = {}
    for r in _select(rows, config):
        trials.setdefault(r["trial"], r.get("failure_kinds", "") or "")
        why = r.get("not_calibrated", "") or ""
        if not r["calibrated"]:
            reason = why.split(":", 1)[0] or "unknown"
            reasons[reason] = reasons.get(reason, 0) + 1
    kinds: dict[str, int] = {}
    for cell in trials.values():
        for part in filter(None, (p.strip() for p in cell.split(";"))):
            kind, _, count = part.rpartition(" ")
            kinds[kind] = kinds.get(kind, 0) + int(count)
    return {
        "kinds": dict(sorted(kinds.items(), key=lambda kv: (-kv[1], kv[0]))),
        "trials_with_failures": sum(1 for cell in trials.values() if cell),
        "not_calibrated": dict(sorted(reasons.items(), key=lambda kv: (-kv[1], kv[0]))),
    }


def summarise(rows: Sequence[dict[str, Any]], settings: dict[str, Any]) -> dict[str, Any]:
    """Everything ``summary.json`` holds."""
    return {
        **settings,
        "trials_done": len({r["trial"] for r in rows if r["config"] == ALL}),
        "visits": visit_summary(rows),
        "failures": failure_summary(rows),
        "parent_final": parent_summary(rows),
        "budget": budget(rows),
        "paper": against_paper(rows) if applies(rows) else None,
    }
