"""The paper's numbers as Monte-Carlo targets, and the fit of unknown error sources to them:
pure parts on synthetic tables with a known truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin.montecarlo.error_fit import (
    FitParameter,
    fit_error_model,
    log_spread,
)
from twin.montecarlo.paper_targets import (
    LOCAL_BAND,
    TARGETS,
    WORLD_BAND,
    against_paper,
    applies,
    matched,
    percentile_of,
    trial_values,
)
from twin.montecarlo.trial import COLUMNS
from twin.report.paper import TABLE_III

PAPER_VISITS = [("cam1", 1), ("cam2", 1), ("cam3", 1), ("cam2", 2), ("cam1", 2)]


def _rows(trials: int, value, offset, config: str = "all") -> list[dict]:
    """A table of ``trials`` trials of the paper's visits: every Table III metric of trial
    t and visit v is ``value(t, v)``, the camera's centre offset ``offset(t, v)`` (3,)."""
    rows = []
    for t in range(trials):
        for camera, visit in PAPER_VISITS:
            row = dict.fromkeys(COLUMNS, math.nan)
            d = offset(t, (camera, visit))
            x = value(t, (camera, visit))
            row.update(
                config=config,
                trial=t,
                seed=t,
                camera=camera,
                visit=visit,
                calibrated=1,
                world_pixel_mean=x,
                world_error_3d_mean_mm=10 * x,
                local_pixel_mean=x / 2,
                local_error_3d_mean_mm=5 * x,
                position_dx_mm=d[0],
                position_dy_mm=d[1],
                position_dz_mm=d[2],
            )
            rows.append(row)
    return rows


def test_the_targets_are_table_iii_and_both_repeatabilities():
    assert len(TARGETS) == 18
    kinds = [t.kind for t in TARGETS]
    assert kinds.count("local") == 8
    assert kinds.count("world") == 8
    rep = {t.camera: t.paper for t in TARGETS if t.kind == "repeatability"}
    assert rep["cam1"] == pytest.approx(math.hypot(37.7, 18.9, -1.1))
    assert rep["cam2"] == pytest.approx(math.hypot(39.0, -24.57, -10.56))
    first = next(t for t in TARGETS if t.camera == "cam1" and t.visit == 2 and t.kind == "world")
    assert first.paper == TABLE_III[3].world_pixel


def test_a_repeatability_is_the_norm_of_the_last_centre_minus_the_first():
    offsets = {("cam1", 1): (1.0, 2.0, 2.0), ("cam1", 2): (4.0, 6.0, 2.0)}
    rows = _rows(3, lambda t, v: 1.0, lambda t, v: np.array(offsets.get(v, (0, 0, 0))) * (t + 1))
    target = next(t for t in TARGETS if t.name == "cam1 repeatability mm")
    np.testing.assert_allclose(trial_values(rows, target), [5.0, 10.0, 15.0])


def test_the_paper_is_placed_among_the_trials():
    rng = np.random.default_rng(3)
    values = rng.lognormal(0.0, 0.3, size=(400, len(PAPER_VISITS)))
    index = {v: k for k, v in enumerate(PAPER_VISITS)}
    rows = _rows(400, lambda t, v: values[t, index[v]], lambda t, v: np.zeros(3))
    assert applies(rows)
    assert not applies([r for r in rows if r["camera"] != "cam2"])
    out = {e["name"]: e for e in against_paper(rows)}
    e = out["cam1 (2nd) world px"]
    v = values[:, index[("cam1", 2)]]
    assert e["median"] == pytest.approx(np.median(v))
    assert e["paper_percentile"] == pytest.approx(100 * np.mean(v < 8.54))
    assert e["ratio"] == pytest.approx(np.median(v) / 8.54)
    assert not e["matched"]
    # Every trial has zero repeatability: the paper's 42 mm lies above all of them.
    assert out["cam1 repeatability mm"]["paper_percentile"] == 100.0
    assert not out["cam1 repeatability mm"]["matched"]


def test_the_bands_follow_the_kind_of_entry():
    local, world, rep = (
        next(t for t in TARGETS if t.kind == kind) for kind in ("local", "world", "repeatability")
    )
    assert matched(local, local.paper * (1 + 0.99 * LOCAL_BAND), 0, 0)
    assert not matched(local, local.paper * (1 + 1.01 * LOCAL_BAND), 0, 0)
    assert matched(world, world.paper * (1 - 0.99 * WORLD_BAND), 0, 0)
    assert not matched(world, world.paper * (1 - 1.01 * WORLD_BAND), 0, 0)
    assert matched(rep, 1000.0, rep.paper - 1, rep.paper + 1)
    assert not matched(rep, rep.paper, rep.paper + 1, rep.paper + 2)
    assert not matched(local, math.nan, 0, 0)


def test_percentile_counts_ties_half_and_is_nan_without_values():
    assert percentile_of(np.array([1.0, 2.0, 3.0, 4.0]), 2.0) == pytest.approx(37.5)
    assert math.isnan(percentile_of(np.array([]), 1.0))


# -- the fit ---------------------------------------------------------------------------------
def _synthetic_twin(truth: np.ndarray, trials: int = 400):
    """An evaluator whose metrics follow known laws of two sources ``a`` (px) and ``b``
    (mm), with lognormal scatter over trials (the same draws at every call), and the
    paper's values replaced by that twin's own medians at ``truth``."""
    rng = np.random.default_rng(11)
    scatter = rng.lognormal(0.0, 0.2, size=(trials, len(PAPER_VISITS)))
    index = {v: k for k, v in enumerate(PAPER_VISITS)}

    def evaluate(values):
        a, b = values["noise.a"], 1e3 * values["noise.b"]

        # Local errors grow with both sources, the later visits' world errors with b alone.
        def value(t, v):
            level = math.hypot(a, 0.3 * b) * (1.0 + 0.5 * (v[1] == 2) * b)
            return level * scatter[t, index[v]]

        return _rows(trials, value, lambda t, v: np.array([b * (v[1] == 2), 0.0, 0.0]) * 10)

    return evaluate


def test_the_fit_recovers_known_sources_from_their_own_medians():
    truth = np.array([0.6, 1.5])  # a px, b mm
    evaluate = _synthetic_twin(truth)
    rows = evaluate({"noise.a": truth[0], "noise.b": truth[1] * 1e-3})
    medians = {t.name: float(np.median(trial_values(rows, t))) for t in TARGETS}
    targets = tuple(
        type(t)(t.camera, t.visit, t.kind, t.unit, medians[t.name])
        for t in TARGETS
        if medians[t.name] > 0
    )
    params = (
        FitParameter("noise.a", "px", 1.0, 3.0, (0.1, 1.0)),
        FitParameter("noise.b", "mm", 1e3, 10.0, (0.2, 3.0)),
    )
    fit = fit_error_model(evaluate, params, [0.3, 3.0], targets)
    np.testing.assert_allclose(fit.values, truth, rtol=1e-3)
    assert np.all(np.abs(fit.residuals) < 1e-3)
    assert np.all(np.isfinite(fit.std))
    assert np.all(fit.std > 0)
    assert fit.plausible() == [True, True]
    assert fit.scenario_values() == pytest.approx(
        {"noise.a": truth[0], "noise.b": truth[1] * 1e-3}, rel=1e-3
    )


def test_a_start_outside_the_bounds_is_refused():
    params = (FitParameter("noise.a", "px", 1.0, 3.0, (0.1, 1.0)),)
    with pytest.raises(ValueError, match="start"):
        fit_error_model(lambda v: [], params, [5.0])
    with pytest.raises(ValueError, match="none of the targets"):
        fit_error_model(lambda v: [], params, [1.0])


def test_log_spread_is_the_half_range_of_the_log():
    rng = np.random.default_rng(0)
    v = rng.lognormal(0.0, 0.25, 20_000)
    # Half the 16-84 % range of a normal is its standard deviation; 20 000 draws pin it
    # to well within 2 %.
    assert log_spread(v) == pytest.approx(0.25, rel=0.02)
    assert math.isnan(log_spread(np.array([1.0])))
