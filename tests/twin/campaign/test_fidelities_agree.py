"""The two fidelities agree on the paper's hall.

One seed runs at both fidelities. The instrument's noise is keyed to what each shot
measures, so both runs draw the same instrument errors where they measure the same things;
what differs is what the fidelities model differently (robots driven on wheel odometry or
placed with a stopping error, LEDs found in rendered images or projected with detection
noise). The local-frame errors average 70 points each and are driven by that shared noise:
they must agree closely, visit by visit.

The camera position errors are single heavy-tailed values per calibration, held here only
to what the run predicts for them; whether their magnitudes agree is measured over
Monte-Carlo trials by ``benchmarks/bench_fidelity.py`` (30 trials a fidelity; the pooled
medians agree within a few tens of per cent). Over a
handful of seeds the median cannot decide a factor of 1.5: two batches of three seeds of
the *same* fidelity fall more than 1.5 apart in about a quarter of draws.
"""

from pathlib import Path

import pytest

from twin.montecarlo.prediction import predictions_from_log
from twin.record import read_log
from twin.report.reading import planned_visits
from twin.run.runner import run_scenario
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

ROOT = Path(__file__).resolve().parents[3]
HALL = ROOT / "scenarios" / "paper_hall.toml"
SEED = 1

LOCAL_AGREEMENT = 0.2
"""Largest relative difference of a visit's local-frame errors between the fidelities. The
shared noise leaves the LED detection (0.05 px projected noise against what the detector
finds in rendered images) and the robots' stops, centimetres apart: measured at most 10 %."""


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """Each fidelity's results and the folder it wrote them to. Without the reference data
    sets (cam1's and cam2's from the start: two data sets of the seven, none of it in the
    local errors or the camera positions compared here)."""
    hall = with_values(load_scenario(HALL), {"campaign.reference_cameras": []})
    out = {}
    for fidelity in ("geometric", "render"):
        folder = tmp_path_factory.mktemp(fidelity)
        results = run_scenario(
            hall, folder, fidelity=fidelity, seed=SEED, report=False, strategy="paper"
        )
        out[fidelity] = (results, folder)
    return out


@pytest.fixture(scope="module")
def runs(outputs):
    return {fidelity: results for fidelity, (results, _) in outputs.items()}


def test_both_fidelities_calibrate_every_visit_with_all_points(runs):
    planned = [(*key, 70) for key, _ in planned_visits(load_scenario(HALL))]
    assert len(planned) == 5
    for results in runs.values():
        assert results["complete"]
        made = [(c["camera"], c["visit"], c["points"]) for c in results["calibrations"]]
        assert made == planned


@pytest.mark.parametrize("metric", ["pixel_mean", "error_3d_mean_mm"])
def test_local_errors_agree_visit_by_visit(runs, metric):
    geo, ren = (runs[f]["calibrations"] for f in ("geometric", "render"))
    for g, r in zip(geo, ren, strict=True):
        a, b = g["errors"]["local"][metric], r["errors"]["local"][metric]
        assert abs(b - a) <= LOCAL_AGREEMENT * a, (g["camera"], g["visit"], a, b)


# A camera's position error over the RMS the run predicts for it (the transfer of the
# parent's pose and the calibration's own covariance, from the log), measured over 80
# seeds of the hall at the geometric fidelity: RMS 1.07-1.90 by visit (the prediction
# takes the LED positions as exact), largest 4.8. One draw's tail is at most that of a
# half-normal of the largest RMS: 1e-5 lies 4.42 of it out; the render fidelity's errors
# are within a few tens of per cent of the geometric's (bench_fidelity.py), allowed for by
# half as much again. Ten values: a false alarm once in 10 000 runs.
ERROR_OVER_PREDICTED = 4.42 * 1.90 * 1.5


def test_camera_errors_are_what_the_run_predicts_at_both(outputs):
    for results, folder in outputs.values():
        predicted, _ = predictions_from_log(read_log(folder / "log.mcap").messages)
        rms = {(p.camera, p.visit): 1e3 * p.rms_m for p in predicted}
        for c in results["calibrations"]:
            error = c["truth"]["position_error_mm"]
            assert 0.0 < error < ERROR_OVER_PREDICTED * rms[(c["camera"], c["visit"])], c
