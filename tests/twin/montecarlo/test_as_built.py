"""The paper's hall as built (its error model fitted to the paper's Table III): it loads,
runs at the geometric and batch fidelities, and a short Monte Carlo lands near the paper's
local errors; its report puts the paper beside the twin."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.montecarlo.paper_targets import TARGETS, trial_values
from twin.montecarlo.run import run_montecarlo
from twin.report.paper import TABLE_III
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
AS_BUILT = SCENARIOS / "paper_hall_as_built.toml"


@pytest.fixture(scope="module")
def as_built():
    return load_scenario(AS_BUILT)


def test_the_as_built_hall_is_the_paper_hall_with_another_error_model(as_built):
    hall = load_scenario(SCENARIOS / "paper_hall.toml")
    assert as_built.space == hall.space
    # The same cameras; camera 2 has its own centroid error.
    own = {c.name: c.led_centroid_px for c in as_built.cameras}
    assert own["cam1"] is None
    assert own["cam2"] > as_built.noise.led_centroid_px
    assert own["cam3"] is None
    same = tuple(c.model_copy(update={"led_centroid_px": None}) for c in as_built.cameras)
    assert same == hall.cameras
    assert as_built.route == hall.route
    assert as_built.calibration == hall.calibration
    assert as_built.campaign.strategy == "paper"
    # The fitted sources are on, and the campaign is told what a user would know.
    assert as_built.noise.led_centroid_px > 0
    assert as_built.noise.marker_geometry_m > 0
    assert as_built.noise.child_creep_m > 0
    assert as_built.marker.survey_sigma_m == as_built.noise.marker_geometry_m
    assert as_built.campaign.child_creep_m == as_built.noise.child_creep_m
    # The instrument keeps its datasheet.
    assert as_built.noise.total_station == hall.noise.total_station


@pytest.fixture(scope="module")
def short_monte_carlo(as_built, tmp_path_factory):
    out = tmp_path_factory.mktemp("as_built")
    rows = run_montecarlo(as_built, out, 60, master_seed=3, strategy="paper", workers=1)
    return rows, out


def test_a_short_monte_carlo_lands_near_the_papers_local_errors(short_monte_carlo):
    rows, _ = short_monte_carlo
    # Each local median of 60 trials: the trials' spread of the log is about 0.08 (the
    # fit's table), so the median of 60 is within 2 % (one sigma) of the twin's median,
    # itself within 22 % of the paper's. The band, 0.6 to 1.6 times the paper's value,
    # cannot be left by chance. It guards the term that sets the local errors, the cameras'
    # centroid error: without it they fall to about half the paper's, doubled they rise to
    # 1.4-2.2 times (and the datasheet model gives 0.2-0.4). The marker's share of them is
    # smaller than this band; the fit pins it, not this test.
    for target in TARGETS:
        if target.kind != "local":
            continue
        median = float(np.median(trial_values(rows, target)))
        assert 0.6 * target.paper < median < 1.6 * target.paper, target.name
    # World errors grow along the route as in the paper: the last visit's are several times
    # the first's (paper: 8.4 times in pixels; the as-built twin about 6.7, 1.9 without the
    # children's creep).
    first, last = (
        float(np.median(trial_values(rows, t)))
        for t in TARGETS
        if t.kind == "world" and t.unit == "px" and t.camera == "cam1"
    )
    assert last > 3 * first


def test_the_report_sets_the_paper_beside_the_twin(short_monte_carlo):
    _, out = short_monte_carlo
    report = (out / "report.md").read_text()
    assert "## Against the paper (Table III and the repeatability)" in report
    for col in TABLE_III:
        assert f"| {col.local_pixel:.2f} |" in report
        assert f"| {col.world_3d_mm:.2f} |" in report
    assert "| cam1 repeatability mm | 42.19 |" in report
    assert (out / "figures" / "paper_percentiles.png").stat().st_size > 10_000


def test_the_as_built_campaign_calibrates_every_visit_at_the_geometric_fidelity(as_built, tmp_path):
    results = run_scenario(
        as_built, tmp_path, fidelity="geometric", seed=5, report=False, strategy="paper"
    )
    visits = {(c["camera"], c["visit"]) for c in results["calibrations"]}
    assert visits == {("cam1", 1), ("cam2", 1), ("cam3", 1), ("cam2", 2), ("cam1", 2)}
    assert not results["skipped_visits"]
