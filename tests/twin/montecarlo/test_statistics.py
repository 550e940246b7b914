"""On the smoke scenario, the Monte-Carlo spread of the parent's final position agrees
with the covariance that CPS propagates along the way."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.montecarlo import run_montecarlo
from twin.montecarlo.summary import parent_summary
from twin.scenario import load_scenario

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"
TRIALS = 60


@pytest.mark.slow
def test_parent_final_spread_agrees_with_the_propagated_covariance(tmp_path):
    rows = run_montecarlo(load_scenario(SMOKE), tmp_path, TRIALS, master_seed=2026)
    s = parent_summary(rows)
    assert s["trials"] == TRIALS
    # The 3D RMS pools three axes over 60 trials: its sampling error is about
    # 1 / sqrt(2 * 3 * 60) = 5 %, so 20 % is four standard errors.
    assert s["rms_3d"]["mc_over_predicted"] == pytest.approx(1.0, abs=0.2)
    # Each axis alone (9 % sampling error): a wrong axis of the covariance shows here.
    for axis in "xyz":
        assert s[axis]["mc_over_predicted"] == pytest.approx(1.0, abs=0.35), axis
        # No bias beyond three standard errors of the mean.
        assert abs(s[axis]["mc_mean_mm"]) < 3 * s[axis]["mc_std_mm"] / TRIALS**0.5, axis
