"""The global adjustment on a synthetic loop with a known truth (:mod:`.network_loop`):
exact without noise, better than the sequential CPS calibrations with it, a covariance that
matches the Monte-Carlo spread, and a named refusal when nothing was measured twice."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.rotation import wrap_angle
from calib.tsai import tsai_from_vector
from tests.twin.localization.network_loop import Noise, make_loop
from twin.localization.adjustment import NothingToAdjustError, adjust_network


def _positions(adjusted) -> np.ndarray:
    return np.array([tsai_from_vector(q, (320, 240)).position for q in adjusted.cameras])


def test_a_noise_free_loop_is_recovered_exactly_from_a_wrong_start():
    loop = make_loop(np.random.default_rng(0), Noise(0.0, 0.0, 0.0, 0.0), control=True)
    net = loop.network
    assert_allclose(loop.sequential, np.tile(loop.camera.position, (2, 1)), atol=1e-9)
    wrong = net.cameras.copy()
    wrong[:, 8:11] += [0.01, -0.02, 0.015]  # the camera's centre 2.7 cm off
    wrong[:, 5:8] += 2e-3  # its rotation 3.5 mrad off
    wrong[:, 0] *= 1.02
    stations = net.stations.copy()
    stations[1:, 0] += 1e-3
    stations[1:, 1:3] += 0.01
    start = dataclasses.replace(net, cameras=wrong, stations=stations)
    adjusted = adjust_network(start)
    assert_allclose(_positions(adjusted)[0], loop.camera.position, atol=1e-7)
    assert_allclose(adjusted.stations[:, 1:], loop.stations[:, 1:], atol=1e-8)
    assert_allclose(wrap_angle(adjusted.stations[:, 0] - loop.stations[:, 0]), 0.0, atol=1e-9)
    assert adjusted.cameras[0, 0] == pytest.approx(loop.camera.f, rel=1e-8)


@pytest.fixture(scope="module")
def loops():
    """40 noisy loops closed by a control point, their adjustments (one camera), and the
    same loops' sequential calibrations."""
    rng = np.random.default_rng(2024)
    out = []
    for _ in range(40):
        loop = make_loop(rng, control=True)
        out.append((loop, adjust_network(loop.network)))
    return out


def test_the_adjusted_revisit_is_better_than_the_sequential_one(loops):
    # 40 loops: the sequential revisit's RMS error is about 4 times the adjusted one here;
    # asking for half leaves a margin far beyond the sampling spread of either RMS (~11 %).
    seq = np.array([np.linalg.norm(lp.sequential[1] - lp.camera.position) for lp, _ in loops])
    adj = np.array([np.linalg.norm(_positions(a)[0] - lp.camera.position) for lp, a in loops])
    assert np.sqrt(np.mean(adj**2)) < 0.5 * np.sqrt(np.mean(seq**2))


def test_the_adjusted_covariance_matches_the_spread(loops):
    # The camera centre's error against its predicted covariance: chi-square with 3 degrees
    # of freedom, so its mean over 40 loops is 3 with a standard deviation of
    # sqrt(6 / 40) = 0.39; the bounds are 2.5 of them either side.
    chi2 = []
    for loop, adjusted in loops:
        err = _positions(adjusted)[0] - loop.camera.position
        chi2.append(err @ np.linalg.solve(adjusted.camera_covariances[0][8:, 8:], err))
    assert 2.0 < np.mean(chi2) < 4.0
    # And the chi-square of the whole network is near its degrees of freedom.
    ratios = [a.variance_factor for _, a in loops]
    assert 0.85 < np.mean(ratios) < 1.15


def test_per_visit_cameras_are_tied_by_the_control_point():
    rng = np.random.default_rng(7)
    loop = make_loop(rng, control=True, cameras="per_visit")
    adjusted = adjust_network(loop.network)
    assert len(adjusted.cameras) == 2
    last = len(loop.stations) - 1
    assert adjusted.redundancy == (f"control point start from stations [0, {last}]",)


def test_nothing_measured_twice_is_refused_by_name():
    loop = make_loop(np.random.default_rng(3), control=False, cameras="per_visit")
    with pytest.raises(NothingToAdjustError, match="nothing was measured twice"):
        adjust_network(loop.network)
    # Asked for anyway, it solves: the stations stay CPS's to first order.
    adjusted = adjust_network(loop.network, require_redundancy=False)
    assert_allclose(adjusted.stations[:, 1:], loop.network.stations[:, 1:], atol=2e-4)


def test_a_control_point_seen_from_one_station_adds_nothing():
    loop = make_loop(np.random.default_rng(4), control=True, cameras="per_visit")
    net = loop.network
    once = tuple(
        s for s in net.point_sightings if not (net.control_targets[s.target] and s.station)
    )
    with pytest.raises(NothingToAdjustError):
        adjust_network(dataclasses.replace(net, point_sightings=once))


def test_the_survey_unknowns_derivatives_are_the_residuals():
    # Each stop loads on its child's survey error (two children, of 12 and 6 components):
    # the Jacobian's columns for those unknowns, and for the stations they turn with, are
    # the residuals' central differences.
    from twin.localization.adjustment import _Problem

    loop = make_loop(np.random.default_rng(5), control=True)
    rng = np.random.default_rng(6)
    sightings = tuple(
        dataclasses.replace(
            s,
            child=f"child{1 + k % 2}",
            survey_level=rng.normal(0.0, 2e-3, (s.leds_level.size, 12 if k % 2 == 0 else 6)),
        )
        for k, s in enumerate(loop.network.led_sightings)
    )
    # The loop's cameras are seen from stations facing east and west: turn every station
    # (the derivatives hold wherever the residuals are taken).
    stations = loop.network.stations.copy()
    stations[:, 0] += 1.2
    net = dataclasses.replace(loop.network, led_sightings=sightings, stations=stations)
    yaws = stations[[s.station for s in sightings], 0]
    assert np.abs(np.sin(yaws)).min() > 0.9
    problem = _Problem(net)
    x = problem.layout.pack(net)
    assert problem.layout.size - problem.layout.camera_end == 18
    x[problem.layout.camera_end :] = rng.normal(0.0, 1.0, 18)
    _, jac = problem.residuals_and_jacobian(x)
    columns = list(range(problem.layout.camera_end, problem.layout.size))
    columns += [0, 4, 8]  # the yaw of stations 1, 2 and 3
    for c in columns:
        step = np.zeros_like(x)
        step[c] = 1e-6
        plus, _ = problem.residuals_and_jacobian(x + step)
        minus, _ = problem.residuals_and_jacobian(x - step)
        numeric = (plus - minus) / 2e-6
        assert_allclose(jac[:, [c]].toarray().ravel(), numeric, rtol=1e-4, atol=1e-6)
    # The prior: one residual a component, the component itself.
    assert_allclose(problem.residuals_and_jacobian(x)[0][-18:], x[-18:])
