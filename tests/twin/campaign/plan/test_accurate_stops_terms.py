"""The accuracy planner's terms, each against what it stands for: a point's covariance from
the total station's noise (by hand), the calibrated camera's predicted position covariance
(the first-order response of the batched calibration itself, by finite differences) and
the stops' order (seeds, greedy choices by brute force, then the rest in order)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.tsai import pixel_jacobian
from calib.tsai_lm import calibrate_tsai_batch
from twin.campaign.plan.accurate_stops import (
    PLAN_PIXEL_PX,
    SEED_POINTS,
    choose_stops,
    partial_view_stops,
    point_covariance,
    predicted_position_covariance,
)
from twin.instruments.total_station import TotalStationSpec
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[4]
SPEC = TotalStationSpec(
    distance_sigma_const=0.002,
    distance_sigma_ppm=2000.0,
    angle_sigma=3e-4,
    pointing_sigma=0.0015,
)
"""Every term of the same order at a few metres: distance 2 mm + 2 mm/m, angles 0.3 mm/m,
pointing 1.5 mm."""

PIXEL_PX = 1.0


def test_a_points_covariance_is_the_distance_along_the_sight_the_angles_across_and_the_aim():
    instrument = np.array([1.0, -2.0, 0.5])
    u = np.array([0.6, 0.8, 0.0])  # the line of sight, 5 m long
    across = (np.array([-0.8, 0.6, 0.0]), np.array([0.0, 0.0, 1.0]))
    cov = point_covariance(instrument + 5.0 * u, instrument, SPEC)
    along_var = (0.002 + 2000e-6 * 5.0) ** 2 + 0.0015**2  # 12 mm, and the aim
    across_var = (3e-4 * 5.0) ** 2 + 0.0015**2  # 1.5 mm each, and the aim
    assert u @ cov @ u == pytest.approx(along_var, rel=1e-12)
    for w in across:
        assert w @ cov @ w == pytest.approx(across_var, rel=1e-12)
        assert u @ cov @ w == pytest.approx(0.0, abs=1e-18)
    assert across[0] @ cov @ across[1] == pytest.approx(0.0, abs=1e-18)
    # Arrays of points: one covariance each.
    many = point_covariance(np.stack([instrument + 5.0 * u, instrument + 2.0 * across[1]]),
                            instrument, SPEC)  # fmt: skip
    assert_allclose(many[0], cov)
    vertical = (0.002 + 2000e-6 * 2.0) ** 2 + 0.0015**2
    assert many[1][2, 2] == pytest.approx(vertical, rel=1e-12)
    assert many[1][0, 0] == pytest.approx((3e-4 * 2.0) ** 2 + 0.0015**2, rel=1e-12)


@pytest.fixture(scope="module")
def smoke():
    sc = load_scenario(ROOT / "scenarios" / "smoke.toml")
    visit = sc.calibration.visits[0]
    parent = np.asarray(visit.station, dtype=float)
    camera = sc.camera(visit.camera).tsai()
    candidates = partial_view_stops(
        sc.space, sc.marker.assembly(), (SPEC.range_min, SPEC.range_max), camera, parent, 0.0, None
    )
    return camera, np.array([parent[0], parent[1], 0.0]), candidates


def test_the_predicted_position_covariance_is_the_calibrations_first_order_response(smoke):
    # The calibration's optical centre moved by each point's error along each axis of its
    # covariance's square root, and by each pixel's: (G L)(G L)^T + sigma^2 H H^T is the
    # first-order covariance the prediction stands for; the responses G L and H are
    # measured on the batched calibration itself, every step at once. A pixel noise of
    # 1 px makes the pixels' part of the order of the points'.
    camera, instrument, candidates = smoke
    points = np.concatenate([c.leds_world[c.shown] for c in candidates[:12]])[:30]
    n = len(points)
    pixels = camera.project(points)
    roots = np.linalg.cholesky(point_covariance(points, instrument, SPEC))  # (n, 3, 3)
    h = 0.01
    moves_p, moves_uv = [], []
    for i in range(n):
        for k in range(3):
            step = np.zeros((n, 3))
            step[i] = h * roots[i][:, k]
            moves_p += [points + step, points - step]
        for k in range(2):
            step = np.zeros((n, 2))
            step[i, k] = h * PIXEL_PX
            moves_uv += [step, -step]
    p3 = np.concatenate([np.stack(moves_p), np.repeat(points[None], len(moves_uv), 0)])
    uv = np.concatenate([np.repeat(pixels[None], len(moves_p), 0), pixels + np.stack(moves_uv)])
    # The steps move the pixels by 1 % of their noise: a convergence test at 0.01 px (of
    # the fit's standard deviations) stops far inside them.
    fit = calibrate_tsai_batch(p3, uv, camera.image_size, camera, min_sigma_px=1e-2)
    assert fit.converged.all()
    response = (fit.position[0::2] - fit.position[1::2]) / (2 * h)  # (3n + 2n, 3)
    want = response.T @ response
    got = predicted_position_covariance(camera, points, instrument, SPEC, PIXEL_PX)
    std = np.sqrt(np.diag(want))
    assert_allclose(np.sqrt(np.diag(got)), std, rtol=2e-3)
    assert_allclose(got / np.outer(std, std), want / np.outer(std, std), atol=2e-3)
    # Both parts count: the points' part and the pixels' are of one order here.
    points_part = response[: 3 * n].T @ response[: 3 * n]
    assert 0.2 < np.trace(points_part) / np.trace(want) < 0.8


GREEDY_SPEC = TotalStationSpec()
"""The instrument of the stops' test: the paper's, whose points' errors seen from the
camera are of the order of the plan's 0.05 px of pixel noise (both weigh the choice)."""


def _information(camera, candidates, instrument) -> np.ndarray:
    """(N, 11, 11) each candidate's Fisher information of Tsai's internal parameters: each
    LED it shows with its pixel noise plus its point's error projected (the module's
    text), written out here."""
    out = np.zeros((len(candidates), 11, 11))
    for k, c in enumerate(candidates):
        leds = c.leds_world[c.shown]
        jac = pixel_jacobian(camera, leds)  # (m, 2, 11)
        grad = -jac[..., 8:11]
        cov = grad @ point_covariance(leds, instrument, GREEDY_SPEC) @ np.swapaxes(grad, 1, 2)
        cov = cov + PLAN_PIXEL_PX**2 * np.eye(2)
        out[k] = np.einsum("mri,mrs,msj->ij", jac, np.linalg.inv(cov), jac)
    return out


def test_the_stops_are_the_seeds_the_greedy_choices_then_the_rest_in_order(smoke):
    camera, instrument, candidates = smoke
    candidates = candidates[::3]  # fewer, for the brute force
    points = 20
    planned, spares = choose_stops(candidates, camera, instrument, GREEDY_SPEC, points)
    index = {id(c): i for i, c in enumerate(candidates)}
    order = [index[id(c)] for c in planned + spares]
    assert sorted(order) == list(range(len(candidates)))  # each candidate once
    shown = np.array([c.points for c in candidates])
    total = np.cumsum(shown[order])
    # The planned stops end where they hold the points asked for.
    assert total[len(planned) - 1] >= points > total[len(planned) - 2]
    info = _information(camera, candidates, instrument)
    # The seeds: the candidates' first, until they hold SEED_POINTS and fix every
    # parameter.
    seeds = 1
    while shown[:seeds].sum() < SEED_POINTS or np.linalg.cond(_unit(info[:seeds].sum(0))) > 1e8:
        seeds += 1
    assert order[:seeds] == list(range(seeds))
    # Then each stop the one that most lowers the trace of the optical centre's covariance,
    # until the chosen hold twice the points asked for.
    chosen = info[:seeds].sum(0)
    at = seeds
    while total[at - 1] < 2 * points:
        left = np.setdiff1d(np.arange(len(candidates)), order[:at])
        before = np.trace(np.linalg.inv(chosen)[8:, 8:])
        after = np.trace(np.linalg.inv(chosen[None] + info[left])[:, 8:, 8:], axis1=1, axis2=2)
        gain = before - after
        picked = gain[np.searchsorted(left, order[at])]
        assert picked >= gain.max() * (1 - 1e-6), (at, order[at], left[np.argmax(gain)])
        chosen = chosen + info[order[at]]
        at += 1
    assert at > seeds + 2  # the greedy choices were tested
    # The rest: in the candidates' order.
    assert order[at:] == sorted(order[at:])
    assert len(order[at:]) > 10


def _unit(info: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.diag(info))
    d = np.where(d > 0, d, 1.0)
    return info / np.outer(d, d)
