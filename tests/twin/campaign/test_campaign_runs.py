"""The campaign end to end in the twin: smoke scenario at both fidelities, the exact case,
injected faults, and the log (results from the log; a killed run keeps what it measured)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from tests.twin.campaign.regression.cases import faulted
from twin.campaign.records import CALIBRATION
from twin.montecarlo.prediction import predictions_from_log
from twin.record import read_log
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
HALL = ROOT / "scenarios" / "paper_hall.toml"


def _check_outputs(out: Path, results: dict) -> None:
    # The log is whole and holds the run: one calibration record a calibration.
    log = read_log(out / "log.mcap")
    assert log.complete
    recorded = [(m.data["camera"], m.data["visit"]) for m in log.messages if m.topic == CALIBRATION]
    assert recorded == [(c["camera"], c["visit"]) for c in results["calibrations"]]
    on_disk = json.loads((out / "results.json").read_text())
    assert on_disk["calibrations"] == json.loads(json.dumps(results["calibrations"]))
    for key in ("scenario", "fidelity", "seed", "calibrations", "repeatability_mm"):
        assert key in on_disk
    for key in ("parent_final_error_mm", "failures"):
        assert key in on_disk
    c = on_disk["calibrations"][0]
    for key in ("camera", "visit", "distance_travelled_m", "points", "parameters", "errors"):
        assert key in c
    assert set(c["errors"]) == {"world", "local"}
    assert {"position_error_mm", "rotation_error_deg"} <= set(c["truth"])
    for suffix in (".json", ".yaml", ".camera_info.yaml"):
        assert (out / "cameras" / f"cam1_visit1{suffix}").exists()


# One run's errors are single draws; their bands come from 200 seeds of the smoke scenario
# at the geometric fidelity (the render fidelity's local errors agree with them within 10 %,
# test_fidelities_agree), each set where one draw passes it once in 10 000:
# - the camera's position error over the calibration's own predicted RMS (its standard
#   deviations of x, y, z): RMS 1.60, largest 3.5. Tsai's covariance takes the LED
#   positions as exact, and the instrument's 3D noise adds the rest. The error's tail is
#   that of its largest axis, a half-normal: 5e-5 lies 4.06 of its RMS out, 6.5;
# - the rotation error: RMS 0.20 deg (largest 0.46: the 0.5 deg this band was set to passed
#   once in a few hundred seeds); by the same tail, 0.82 deg;
# - the local pixel error, a mean over 70 points: 0.229 px, standard deviation 0.032 px
#   over the seeds, normal: 0.229 +- 4.4 standard deviations.
POSITION_OVER_PREDICTED = 4.06 * 1.60
ROTATION_DEG = 4.06 * 0.20
LOCAL_PIXEL = (0.229 - 4.4 * 0.032, 0.229 + 4.4 * 0.032)


@pytest.mark.parametrize("fidelity", ["geometric", "render"])
def test_smoke_runs_end_to_end(tmp_path, fidelity):
    results = run_scenario(SMOKE, tmp_path, fidelity=fidelity, report=False)
    _check_outputs(tmp_path, results)
    assert results["complete"]
    (cal,) = results["calibrations"]
    assert cal["points"] == 70
    predicted_mm = 1e3 * np.linalg.norm([cal["std"][k] for k in "xyz"])
    assert cal["truth"]["position_error_mm"] < POSITION_OVER_PREDICTED * predicted_mm
    assert cal["truth"]["rotation_error_deg"] < ROTATION_DEG
    assert LOCAL_PIXEL[0] < cal["errors"]["local"]["pixel_mean"] < LOCAL_PIXEL[1]
    # The reference set of the camera seen from the start gives the world errors.
    assert cal["errors"]["world"]["points"] == 70


def test_without_noise_every_camera_is_recovered_exactly(tmp_path):
    results = run_scenario(
        HALL, tmp_path, fidelity="geometric", noise=False, report=False, strategy="paper"
    )
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == [
        ("cam1", 1),
        ("cam2", 1),
        ("cam3", 1),
        ("cam2", 2),
        ("cam1", 2),
    ]
    for c in results["calibrations"]:
        assert c["truth"]["position_error_mm"] < 1e-3, c  # 1e-6 m
        assert c["truth"]["rotation_error_deg"] < 1e-6
    assert results["parent_final_error_mm"] < 1e-3
    assert results["distance_travelled_m"] == pytest.approx(85.0, abs=1.0)


def test_faults_are_counted_and_the_run_finishes(tmp_path):
    results = run_scenario(
        faulted(load_scenario(SMOKE)), tmp_path, fidelity="geometric", report=False
    )
    f = results["failures"]
    assert f.get("lost_lock", 0) > 0  # the instrument
    assert f.get("led_occluded", 0) > 0
    assert f.get("point_skipped", 0) > 0
    assert f.get("visit_station_unreachable", 0) == 1  # the base
    assert results["complete"]
    assert [c["visit"] for c in results["calibrations"]] == [1]
    (skipped,) = results["skipped_visits"]
    assert skipped["reason"] == "station_unreachable"


def test_a_killed_run_keeps_what_it_measured(tmp_path):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "twin.cli", "run", str(HALL), "--fidelity", "geometric"]
    cmd += ["--strategy", "paper"]
    proc = subprocess.Popen(
        [*cmd, "--out", str(out), "--no-report"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    log = out / "log.mcap"
    deadline = time.time() + 120
    try:
        # The log's first 160 kB hold some 45 complete shots beside Foxglove's messages
        # (80 kB only 18: killed right at that size, a run kept too few for the test
        # below); the run writes about 1.7 MB.
        while time.time() < deadline and proc.poll() is None:
            if log.exists() and log.stat().st_size > 160_000:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the run finished before it could be killed"
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    contents = read_log(log)
    assert not contents.complete
    topics = contents.topics
    assert "/total_station/shot" in topics
    assert "/campaign/point" in topics
    shots = contents.records("/total_station/shot")
    assert len(shots) > 20
    assert all(np.isfinite(s.distance) for s in shots)
    assert not (out / "results.json").exists()
    # What was recorded still gives results (the reference data sets taken so far).
    from twin.campaign.log_results import results_from_log

    partial = results_from_log(contents.messages)
    assert partial["complete"] is False
    assert partial["reference_sets"]
    assert partial["reference_sets"][0]["points"] > 0


# The hall's errors, measured over 80 seeds at the geometric fidelity, for the test below:
# - the world-frame 3D error of camera 1's second visit (after 85 m) over its first's (after
#   1 m): log of the ratio 1.73 +- 0.69 a seed (the ratio falls below 2 for one seed in 12,
#   the reason "each of three seeds above 2" was a bet); the mean of three seeds' logs
#   falls below zero with probability 1e-5 (4.3 standard deviations);
# - the local-frame 3D error of each visit, a mean over 70 points (mean, standard
#   deviation), about normal: held to 5 standard deviations, 15 values a false alarm once
#   in 100 000 runs;
# - the parent's final position error against its propagated covariance: mean NEES 3.06
#   (80 seeds, consistent); three seeds' NEES sum to chi-square with 9 degrees of freedom,
#   held to its two-sided 1e-4 quantiles.
LOCAL_3D_MM = {
    ("cam1", 1): (0.946, 0.124),
    ("cam2", 1): (1.696, 0.237),
    ("cam3", 1): (1.006, 0.121),
    ("cam2", 2): (1.464, 0.234),
    ("cam1", 2): (1.419, 0.194),
}


def test_world_errors_grow_with_travel_and_local_errors_do_not(tmp_path):
    """The paper's Table III pattern, over three seeds of the hall at the geometric fidelity:
    the world-frame errors of the last calibration (camera 1 after 85 m) exceed the first's
    (camera 1 after 1 m), while the local-frame errors stay at the level of the detection
    noise at every visit; the parent's final error is what CPS predicts."""
    seeds = (1, 2, 3)
    log_growth, nees = [], 0.0
    for seed in seeds:
        out = tmp_path / str(seed)
        res = run_scenario(
            HALL,
            out,
            fidelity="geometric",
            seed=seed,
            report=False,
            strategy="paper",
            cameras=False,
        )
        assert not (out / "cameras").exists()  # asked for none: only the results and log
        cal = {(c["camera"], c["visit"]): c for c in res["calibrations"]}
        first = cal[("cam1", 1)]["errors"]["world"]["error_3d_mean_mm"]
        last = cal[("cam1", 2)]["errors"]["world"]["error_3d_mean_mm"]
        log_growth.append(np.log(last / first))
        for key, (mean, sd) in LOCAL_3D_MM.items():
            local = cal[key]["errors"]["local"]["error_3d_mean_mm"]
            assert abs(local - mean) < 5 * sd, (seed, key, local)
        _, final = predictions_from_log(read_log(out / "log.mcap").messages)
        nees += final.error_m @ np.linalg.solve(final.covariance_m2, final.error_m)
        assert 1e3 * np.linalg.norm(final.error_m) == pytest.approx(res["parent_final_error_mm"])
    assert np.mean(log_growth) > 0.0, log_growth
    dof = 3 * len(seeds)
    assert chi2.ppf(5e-5, dof) < nees < chi2.isf(5e-5, dof), nees
