"""A run's global adjustment, end to end: a small loop in the smoke room (camera 1
calibrated twice, the route closed back to the start, a prism left near the start), run at
the geometric fidelity with noise, adjusted by ``twin run`` and again by ``twin replay``."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from tests.twin.campaign.loop_scenario import loop_scenario
from twin.campaign.adjusted_results import adjusted_results, adjustment_settings
from twin.campaign.network_log import LogNetworkError, network_from_log
from twin.campaign.records import PARENT_FIX
from twin.record import read_log
from twin.run.replay import replay_log
from twin.run.runner import run_scenario
from twin.scenario import ScenarioError
from twin.scenario.loader import scenario_from_dict


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("loop")
    sc = loop_scenario()
    results = run_scenario(sc, out, fidelity="geometric", seed=11, report=False)
    return sc, results, out


def test_a_run_writes_the_adjusted_calibrations_beside_the_sequential(run):
    _, results, out = run
    info = results["adjustment"]
    assert info["status"] == "adjusted", info
    assert info["redundancy"][0] == "camera cam1 from stations [1, 3]"
    assert info["redundancy"][1].startswith("control point start_prism from stations [0, 1, ")
    assert 0.7 < info["variance_factor"] < 1.4  # about 1: the stated noise is the simulated
    seq, adj = results["calibrations"], results["adjusted_calibrations"]
    assert [(c["camera"], c["visit"]) for c in adj] == [(c["camera"], c["visit"]) for c in seq]
    for c in adj:
        assert set(c) == set(seq[0])
        std = np.array([c["std"][k] for k in "xyz"])
        assert np.all(std > 0)
        # Within 5 predicted standard deviations of the truth (a normal 3-vector's length
        # exceeds 5 sigma in fewer than 1e-5 of the runs).
        assert c["truth"]["position_error_mm"] < 5e3 * np.linalg.norm(std)
    written = json.loads((out / "results.json").read_text())
    assert written["adjusted_calibrations"][1]["truth"] == adj[1]["truth"]


def test_a_control_point_the_route_never_passes_is_reported(run):
    _, results, _ = run
    assert results["failures"].get("control_point_never_seen") == 1
    assert not any("far_mark" in r for r in results["adjustment"]["redundancy"])


def test_replay_adjusts_the_log_again_the_same_way(run, tmp_path):
    sc, results, out = run
    again = replay_log(out / "log.mcap", tmp_path / "a", scenario=sc, report=False)
    assert again["adjusted_calibrations"] == results["adjusted_calibrations"]
    per_visit = replay_log(
        out / "log.mcap", tmp_path / "b", scenario=sc, report=False, adjust="per_visit"
    )
    assert per_visit["adjustment"]["redundancy"] == results["adjustment"]["redundancy"][1:]
    a, b = (c["parameters"]["position_mm"] for c in per_visit["adjusted_calibrations"])
    assert a != b  # one camera per visit: two positions
    none = replay_log(out / "log.mcap", tmp_path / "c", scenario=sc, report=False, adjust=None)
    assert "adjusted_calibrations" not in none


def test_replay_refuses_to_adjust_in_opencvs_model(run, tmp_path):
    _, _, out = run
    with pytest.raises(ValueError, match="adjustment works in Tsai's model"):
        replay_log(out / "log.mcap", tmp_path / "x", model="opencv", report=False, adjust="shared")
    refit = replay_log(out / "log.mcap", tmp_path / "z", model="opencv", report=False)
    assert "adjusted_calibrations" not in refit  # OpenCV's model: not adjusted by default
    with pytest.raises(ValueError, match="adjust must be one of"):
        replay_log(out / "log.mcap", tmp_path / "y", report=False, adjust="both")


def test_replay_names_the_flags_that_adjust_or_refit(tmp_path, capsys):
    from twin.cli import main

    log = tmp_path / "log.mcap"
    log.write_bytes(b"")  # refused before it is read
    out = tmp_path / "out"
    assert (
        main(["replay", str(log), "--model", "opencv", "--adjust", "shared", "--out", str(out)])
        == 2
    )
    said = " ".join(capsys.readouterr().out.split())
    assert (
        "error: --adjust shared: the adjustment works in Tsai's model, not OpenCV's; pass "
        "--model tsai (the default) to adjust, or --adjust none to refit in OpenCV's model"
    ) in said
    assert "replay with model" not in said
    assert not out.exists()


def test_without_anything_measured_twice_the_adjustment_says_so(run):
    sc, _, out = run
    messages = [m for m in read_log(out / "log.mcap").messages if "control" not in m.topic]
    result = adjusted_results(messages, cameras="per_visit", **adjustment_settings(sc))
    assert result["adjustment"]["status"] == "nothing_to_add"
    assert "nothing was measured twice" in result["adjustment"]["message"]
    assert result["adjusted_calibrations"] == []


def test_a_log_without_the_fixes_measurements_cannot_be_adjusted(run):
    _, _, out = run
    messages = []
    for m in read_log(out / "log.mcap").messages:
        if m.topic == PARENT_FIX:
            data = {k: v for k, v in m.data.items() if not k.startswith("children_")}
            m = dataclasses.replace(m, data=data)
        messages.append(m)
    with pytest.raises(LogNetworkError, match="do not record the children's measurements"):
        network_from_log(messages)
    assert adjusted_results(messages)["adjustment"]["status"] == "not_possible"


def _scenario_dict(**changes):
    raw = loop_scenario().model_dump(mode="json", exclude={"source"})
    raw.update(changes)
    return raw


def test_a_control_point_outside_the_space_is_refused_by_name():
    raw = _scenario_dict(control_points=[{"name": "p", "position": [20.0, 0.0, 0.0]}])
    with pytest.raises(ScenarioError, match=r"control_points\[0\]\.position"):
        scenario_from_dict(raw)


def test_a_return_to_start_needs_a_route_that_ends_there():
    raw = _scenario_dict()
    raw["route"] = {"waypoints": [[0.0, 0.0], [4.0, 0.0]], "return_to_start": True}
    with pytest.raises(ScenarioError, match=r"route\.waypoints\[1\]"):
        scenario_from_dict(raw)


def test_a_network_the_solver_cannot_solve_leaves_the_run_its_sequential_results(run, monkeypatch):
    import twin.campaign.adjusted_results as module

    def singular(network):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(module, "adjust_network", singular)
    _, _, out = run
    result = module.adjusted_results(read_log(out / "log.mcap").messages)
    assert result["adjustment"]["status"] == "failed"
    assert "Singular matrix" in result["adjustment"]["message"]
    assert result["adjusted_calibrations"] == []


def test_an_adjustment_that_fails_the_global_test_says_so_and_scales_its_stds(run):
    # Weighed with a pixel noise ten times smaller than the simulated one, the pixels
    # disagree far more than stated: chi2/dof near 36 fails the global test, which says
    # so, and the adjusted standard deviations grow by sqrt(chi2/dof).
    sc, _, out = run
    messages = read_log(out / "log.mcap").messages
    settings = adjustment_settings(sc)
    stated = adjusted_results(messages, **settings)
    tight = {
        **settings,
        "pixel_noise_px": {k: v / 10 for k, v in settings["pixel_noise_px"].items()},
    }
    wrong = adjusted_results(messages, **tight)
    ok, bad = stated["adjustment"], wrong["adjustment"]
    assert ok["consistent"] is True
    assert ok["covariance_scale"] == 1.0
    assert bad["consistent"] is False
    assert bad["variance_factor"] > 10
    assert bad["covariance_scale"] == bad["variance_factor"]
    assert "fails the global test" in bad["message"]
    for a, b in zip(stated["adjusted_calibrations"], wrong["adjusted_calibrations"], strict=True):
        ratio = np.array([b["std"][k] / a["std"][k] for k in "xyz"])
        # Unscaled, the wrong weights give standard deviations about half the honest ones
        # (0.4 to 0.6 of them here: the stations' part stays); scaled, they are no smaller.
        assert np.all(ratio > 0.9), ratio


def test_a_surveyed_markers_error_is_adjusted_from_the_log(tmp_path):
    # The children's markers 3 mm off their drawing a coordinate, known to the campaign:
    # the log's stops carry their loadings on each child's survey error, the adjustment
    # takes those errors as unknowns, and its global test holds (without them the stated
    # noise cannot explain the residuals: chi2 / dof of tens).
    from twin.instruments.marker_pose import MarkerPose, survey_covariance
    from twin.report.markdown import render_markdown
    from twin.run.runner import built_markers
    from twin.scenario.overrides import with_values

    values = {"marker.survey_sigma_m": 0.003, "noise.marker_geometry_m": 0.003}
    sc = with_values(loop_scenario(), values)
    results = run_scenario(sc, tmp_path, fidelity="geometric", seed=11, report=False)
    messages = read_log(tmp_path / "log.mcap").messages
    network, _ = network_from_log(messages)
    assert {s.child for s in network.led_sightings if s.survey_level.size} == {"child1", "child2"}
    info = results["adjustment"]
    assert info["status"] == "adjusted", info
    assert 0.6 < info["variance_factor"] < 1.6, info
    assert info["consistent"]
    for c in results["adjusted_calibrations"]:
        std = np.array([c["std"][k] for k in "xyz"])
        assert c["truth"]["position_error_mm"] < 5e3 * np.linalg.norm(std)
    # Where each child's LEDs truly stand off the drawing, in the frame its cubes (as
    # drawn) define: the LEDs' own error less what the cubes' error does to the fit.
    nominal = sc.marker.assembly()
    identity = MarkerPose(np.eye(3), np.zeros(3), np.zeros((6, 6)), 0.0)
    jac = identity.point_jacobian(nominal.cubes_body).reshape(-1, 6)
    gain = identity.point_jacobian(nominal.leds_body).reshape(-1, 6) @ np.linalg.solve(
        jac.T @ jac, jac.T
    )
    survey = info["marker_survey"]
    for child, built in built_markers(sc.model_copy(update={"seed": 11})).items():
        dc, dl = built.cubes_body - nominal.cubes_body, built.leds_body - nominal.leds_body
        true = 1e3 * (dl.ravel() - gain @ dc.ravel())
        got = np.ravel(survey[child]["leds_offset_mm"])
        std = np.ravel(survey[child]["leds_offset_std_mm"])
        # Within 4.5 standard deviations (this seed: the vertical ones 0.9-3.0, the others
        # below 2.1; the vertical ones move together, one camera telling LEDs standing
        # higher from a camera standing lower only by the survey's prior); the adjustment
        # knows them better than the survey does.
        assert np.all(np.abs(got - true) < 4.5 * std), (got - true) / std
        assert np.all(std < 1e3 * np.sqrt(np.diag(survey_covariance(nominal)))), std
    report = render_markdown(sc, results, {}, tmp_path)
    first = survey["child1"]["leds_offset_mm"][0][0]
    assert f"| child1 | 0 | {first:.1f} +/- " in report
    # Adjusted again under a scenario that states another survey: the offsets would be
    # scaled by the wrong factor, so they are not reported.
    other = with_values(sc, {"marker.survey_sigma_m": 0.002})
    again = adjusted_results(messages, **adjustment_settings(other))["adjustment"]
    assert "another marker survey" in again["marker_survey"]["message"]
    assert "Marker survey: the log's stops" in render_markdown(
        other, {**results, "adjustment": again}, {}, tmp_path
    )
