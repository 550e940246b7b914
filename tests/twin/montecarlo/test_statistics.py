"""Over a route of several CPS legs, the Monte-Carlo spread of the parent's final position
agrees with the covariance that CPS propagates along the way.

The route: the corridor scenario's first 13 m, to camera 1's station, in legs of 2 m (seven
legs, seven parent fixes after the start). Over several legs the children placed from one
parent pose share its error, and the parent's next fix inherits that shared part: dropping
the cross-covariances of the CPS state changes the predicted standard deviations of the
final position by -26 %, +156 % and -35 % (x, y, z) on this route, while over the smoke
scenario's single 0.5 m leg it changes nothing.

Measured on this route (200 trials): the mean NEES of the final position is 3.06 (its
expectation 3; standard error 0.18) and the RMS of each axis's normalised error 0.98, 0.99,
1.05; with the cross-covariances dropped (40 trials) 1.71, 0.74 and 1.90.

Each axis's mean squared normalised error over N trials is chi-square with N degrees of
freedom over N for a consistent prediction; the band is its two-sided 1e-4 / 3 quantiles
(a false alarm once in 10 000 runs of the test for the three axes together): for N = 40,
[0.33, 2.21], a standard deviation wrong by a factor 1.5 on any axis.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2, norm

from twin.montecarlo import run_montecarlo
from twin.montecarlo.summary import parent_summary
from twin.scenario import load_scenario

CORRIDOR = Path(__file__).resolve().parents[3] / "scenarios" / "corridor.toml"
TRIALS = 40
FALSE_ALARM = 1e-4
LEG = 2.0
STATION = (13.0, 0.0)


def multi_leg_route():
    """The corridor up to camera 1's station, in legs of LEG metres."""
    sc = load_scenario(CORRIDOR)
    formation = sc.campaign.formation.model_copy(update={"step": LEG})
    visit = sc.calibration.visits[0].model_copy(update={"station": STATION})
    return sc.model_copy(
        update={
            "campaign": sc.campaign.model_copy(update={"formation": formation}),
            "route": sc.route.model_copy(update={"waypoints": ((0.0, 0.0), (14.0, 0.0))}),
            "calibration": sc.calibration.model_copy(update={"visits": (visit,)}),
        }
    )


@pytest.mark.slow
def test_parent_final_spread_agrees_with_the_propagated_covariance(tmp_path):
    sc = multi_leg_route()
    assert sc.calibration.visits[0].camera == "cam1"
    rows = run_montecarlo(sc, tmp_path, TRIALS, master_seed=2026, report=False)
    s = parent_summary(rows)
    assert s["trials"] == TRIALS
    # Several legs: the parent travelled the route to the station.
    assert s["distance_travelled_m"] == pytest.approx(STATION[0], abs=0.1)
    err = np.array([[r[f"parent_final_d{a}_mm"] for a in "xyz"] for r in rows])
    std = np.array([[r[f"parent_predicted_s{a}_mm"] for a in "xyz"] for r in rows])
    z2 = np.mean((err / std) ** 2, axis=0)
    tail = FALSE_ALARM / 3 / 2
    low, high = chi2.ppf(tail, TRIALS) / TRIALS, chi2.isf(tail, TRIALS) / TRIALS
    assert np.all((low < z2) & (z2 < high)), (z2.round(3), low, high)
    # No bias: each axis's mean normalised error is N(0, 1 / N), held to the same tails.
    bias = np.mean(err / std, axis=0) * np.sqrt(TRIALS)
    assert np.all(np.abs(bias) < norm.isf(tail)), bias.round(2)
