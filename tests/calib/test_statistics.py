"""The reported uncertainty is right, and where the estimator reaches the Cramer-Rao bound.

Camera 1 of the paper, 70 LED points. The bound is ``sigma^2 (J^T J)^-1`` for pixel noise
sigma on both coordinates: ``predicted_covariance`` must equal it computed here from the
camera model alone, and the least-squares estimator must reach it where it is linear in
the noise.

What was measured (30 point sets, 200 calibrations each, at 0.03 and 0.3 px), as RMS error
over the bound, parameter by parameter:

- at 0.03 px every parameter on every set lies within 0.996-1.007 of the bound, and the
  reported standard deviation within 0.994-1.010 of the RMS error;
- at 0.3 px, the paper's noise, eight parameters stay within 0.99-1.07 (median 1.00-1.02),
  but cx and ry lie 1.01-1.37 times the bound (median 1.08; above 1.04 on 26 sets of 30)
  and kappa1 1.00-1.15 (median 1.03); the reported standard deviation understates their
  RMS error by up to 17 % (cx, ry) and 13 % (kappa1) on the worst set.

Why: a shift of the image centre along u looks much like a turn of the camera about its
vertical axis, so cx and ry trade against each other along a valley of the cost that is
curved over a 770 px lens's narrow field. At 0.3 px a few calibrations in 200 end 4-7
bound standard deviations off along it, at the true least-squares minimum (an optimisation
restarted from the truth finds the same point), and those heavy tails raise the RMS. It
is the estimator's nonlinearity, not sampling: the excess over the bound scales with the
noise squared (a hundredfold less at 0.03 px, measured 105 times on the median set).

The claims tested, on six point sets of their own (seeds POINT_SETS), with the Monte-Carlo
error reduced by a control variate (:meth:`PointSetRun.mean_square_error`):

- at 0.03 px the RMS error lies within 3 % of the bound on every set and parameter
  (measured over 30 repeats of the test: within 1.4 %, standard deviation at most 0.5 %:
  6 standard deviations of margin), and the reported standard deviation within 5 % of the
  RMS error on each set (measured 2.4 %, standard deviation 0.9 %) and 2 % pooled over the
  sets (measured 0.8 %, standard deviation 0.34 %): a reported standard deviation 5 % off
  fails;
- at 0.3 px, pooled over the six sets, the RMS error of the eight parameters lies within
  7 % of the bound (measured at most 3.8 %, standard deviation at most 0.8 %), that of cx
  and ry at most 30 % above it (measured 1.07-1.15, standard deviation 2.2 %) and that of
  kappa1 at most 20 % (1.01-1.07, 1.6 %); the reported standard deviation of the eight is
  within 7 % of their RMS error, of cx, ry and kappa1 at most 15 % below it (measured
  0.93-1.01).

Every band is at least 5.5 standard deviations of its statistic over the repeats from
what was measured: a false alarm far below once in 10 000 runs (the tails at 0.3 px are
heavier than normal, which the wide margins there allow for).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from calib import calibrate_tsai, predicted_covariance
from calib.camera import TsaiCamera
from calib.synthetic import led_points, paper_camera
from calib.tsai import TSAI_PARAMETERS

CAMERA = paper_camera(1)
N_POINTS = 70
POINT_SETS = (1000, 1001, 1002, 1003, 1004, 1005)
"""Seeds of the LED point sets (``led_points``): six sets, among them the 4th (1003), one of
the sets on which cx and ry depart most from the bound at 0.3 px."""

LOW_PX = 0.03
PAPER_PX = 0.3
TRIALS = {LOW_PX: 80, PAPER_PX: 100}
"""Calibrations per point set at each noise level."""

ANGLES = slice(5, 8)
NONLINEAR = ("cx", "ry", "kappa1_px")
"""The parameters whose estimates are visibly nonlinear in the noise at 0.3 px."""

LOW_BAND = 0.03
"""RMS error / bound at LOW_PX: within 1 +- this on every set and parameter."""
REPORTED_BAND = 0.05
REPORTED_POOLED_BAND = 0.02
"""Reported standard deviation / RMS error at LOW_PX: per set, and pooled over the sets."""
PAPER_LINEAR_BAND = 0.07
"""At PAPER_PX, pooled: RMS error / bound and reported / RMS of the parameters other than
NONLINEAR within 1 +- this."""
PAPER_NONLINEAR_HIGH = {"cx": 1.30, "ry": 1.30, "kappa1_px": 1.20}
"""At PAPER_PX, pooled: the largest RMS error / bound of the NONLINEAR parameters."""
PAPER_REPORTED_LOW = 0.85
"""At PAPER_PX, pooled: the smallest reported / RMS of the NONLINEAR parameters."""

FD_STEPS = np.array([1e-2, 1e-3, 1e-3, 1e-6, 1e-11, 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5])
"""Central-difference steps of the reported parameters (px, -, 1/px^2, rad, m)."""


def true_values(cam: TsaiCamera) -> np.ndarray:
    return np.concatenate(
        [[cam.f, cam.cx, cam.cy, cam.sx, cam.kappa1], cam.rotation_rad, cam.position]
    )


TRUTH = true_values(CAMERA)


def pixels_of(theta: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(2N,) pixels of the points for the reported parameters ``theta``, by the camera
    model alone (none of the calibration's own Jacobians or parametrisation)."""
    cam = TsaiCamera.from_pose(
        f=theta[0],
        cx=theta[1],
        cy=theta[2],
        sx=theta[3],
        kappa1=theta[4],
        rotation_rad=theta[ANGLES],
        position=theta[8:11],
        image_size=CAMERA.image_size,
    )
    return cam.project(points).ravel()


def fisher_jacobian(points: np.ndarray) -> np.ndarray:
    """(2N, 11) Jacobian of the pixels with respect to the reported parameters at the
    truth, by central differences."""
    cols = []
    for i, h in enumerate(FD_STEPS):
        step = np.zeros(len(TRUTH))
        step[i] = h
        cols.append((pixels_of(TRUTH + step, points) - pixels_of(TRUTH - step, points)) / (2 * h))
    return np.column_stack(cols)


@dataclass(frozen=True)
class PointSetRun:
    """Calibrations of one point set at one noise level.

    Attributes:
        bound: (11,) Cramer-Rao standard deviations from ``predicted_covariance``.
        linear_bound: (11,) the same from this module's own Jacobian.
        error: (T, 11) estimate minus truth of each calibration.
        linear_error: (T, 11) what the linearised estimator makes of the same noise,
            ``(J^T J)^-1 J^T noise``: its covariance is ``sigma^2 (J^T J)^-1`` exactly.
        reported: (T, 11) standard deviations each calibration reported.
    """

    bound: np.ndarray
    linear_bound: np.ndarray
    error: np.ndarray
    linear_error: np.ndarray
    reported: np.ndarray

    @property
    def mean_square_error(self) -> np.ndarray:
        """(11,) mean squared error, with the linearised estimator as control variate.

        ``mean(e^2) - mean(e_lin^2) + E[e_lin^2]`` has the expectation of ``e^2`` (the
        last term is known exactly) but far less sampling noise than ``mean(e^2)``: the
        two errors come from the same noise and differ only by the nonlinearity.
        """
        return (
            np.mean(self.error**2, axis=0)
            - np.mean(self.linear_error**2, axis=0)
            + self.linear_bound**2
        )


def simulate(seed: int, sigma: float, trials: int, noise_seed: list[int]) -> PointSetRun:
    """``trials`` calibrations of camera 1 from the point set ``seed`` with pixel noise
    ``sigma`` (px) drawn from ``noise_seed``."""
    points = led_points(CAMERA, N_POINTS, np.random.default_rng(seed))
    pixels = CAMERA.project(points)
    jac = fisher_jacobian(points)
    to_params = np.linalg.solve(jac.T @ jac, jac.T)
    rng = np.random.default_rng(noise_seed)
    error, linear, reported = [], [], []
    for _ in range(trials):
        noise = rng.normal(0.0, sigma, pixels.shape)
        res = calibrate_tsai(points, pixels + noise, CAMERA.image_size)
        e = res.values - TRUTH
        e[ANGLES] = (e[ANGLES] + np.pi) % (2 * np.pi) - np.pi
        error.append(e)
        linear.append(to_params @ noise.ravel())
        reported.append(res.std)
    return PointSetRun(
        bound=np.sqrt(np.diag(predicted_covariance(CAMERA, points, sigma))),
        linear_bound=sigma * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac))),
        error=np.array(error),
        linear_error=np.array(linear),
        reported=np.array(reported),
    )


def monte_carlo(sigma: float, noise_seed: int = 2024) -> list[PointSetRun]:
    """Every point set at the noise level ``sigma`` (px); each level draws its own noise,
    so one level's runs are the same whether the other is run or not."""
    return [
        simulate(seed, sigma, TRIALS[sigma], [noise_seed, seed, round(sigma * 1000)])
        for seed in POINT_SETS
    ]


def rms_over_bound(runs: list[PointSetRun]) -> np.ndarray:
    """(sets, 11) RMS error over the Cramer-Rao bound of each set."""
    return np.array([np.sqrt(r.mean_square_error) / r.bound for r in runs])


def pooled(ratios: np.ndarray) -> np.ndarray:
    """(11,) root mean square of per-set ratios (the RMS over all sets in bound units)."""
    return np.sqrt(np.mean(ratios**2, axis=0))


def reported_over_rms(runs: list[PointSetRun]) -> np.ndarray:
    """(sets, 11) RMS of the reported standard deviations over the RMS error."""
    return np.array([np.sqrt(np.mean(r.reported**2, axis=0) / r.mean_square_error) for r in runs])


def outside(ratios: np.ndarray, low: float, high: float) -> dict[str, list[float]]:
    """The parameters with a ratio outside [low, high], with their ratios."""
    ratios = np.atleast_2d(ratios)
    return {
        name: ratios[:, i].round(3).tolist()
        for i, name in enumerate(TSAI_PARAMETERS)
        if ((ratios[:, i] < low) | (ratios[:, i] > high)).any()
    }


# One fixture per noise level: a worker that runs only one level's tests computes only its
# calibrations (480 at LOW_PX, 600 at PAPER_PX).
@pytest.fixture(scope="module")
def low_noise_runs() -> list[PointSetRun]:
    return monte_carlo(LOW_PX)


@pytest.fixture(scope="module")
def paper_noise_runs() -> list[PointSetRun]:
    return monte_carlo(PAPER_PX)


@pytest.mark.parametrize("seed", POINT_SETS)
def test_the_predicted_covariance_is_the_inverse_fisher_information(seed) -> None:
    # The bound from the model alone: sigma^2 (J^T J)^-1 with J by central differences of
    # the projection, in the reported parameters.
    points = led_points(CAMERA, N_POINTS, np.random.default_rng(seed))
    jac = fisher_jacobian(points)
    expected = PAPER_PX**2 * np.linalg.inv(jac.T @ jac)
    got = predicted_covariance(CAMERA, points, PAPER_PX)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    # The central differences agree with the analytic Jacobian to O(h^2): measured 2e-8 of
    # the standard deviations (correlations included); 1e-6 leaves room for rounding.
    np.testing.assert_allclose(got / scale, expected / scale, rtol=0, atol=1e-6)


@pytest.mark.slow
def test_the_estimator_reaches_the_bound_at_low_noise_on_every_set(low_noise_runs) -> None:
    ratios = rms_over_bound(low_noise_runs)
    bad = outside(ratios, 1 - LOW_BAND, 1 + LOW_BAND)
    assert not bad, f"RMS error / Cramer-Rao bound at {LOW_PX} px outside 1 +- {LOW_BAND}: {bad}"


@pytest.mark.slow
def test_at_the_papers_noise_only_cx_ry_and_kappa1_exceed_the_bound(paper_noise_runs) -> None:
    ratio = pooled(rms_over_bound(paper_noise_runs))
    by_name = dict(zip(TSAI_PARAMETERS, ratio.round(3), strict=True))
    for name, r in by_name.items():
        high = PAPER_NONLINEAR_HIGH.get(name, 1 + PAPER_LINEAR_BAND)
        assert 1 - PAPER_LINEAR_BAND <= r <= high, (name, by_name)


@pytest.mark.slow
def test_the_reported_std_is_the_rms_error_at_low_noise(low_noise_runs) -> None:
    ratios = reported_over_rms(low_noise_runs)
    bad = outside(ratios, 1 - REPORTED_BAND, 1 + REPORTED_BAND)
    assert not bad, f"reported std / RMS error outside 1 +- {REPORTED_BAND}: {bad}"
    bad = outside(pooled(ratios), 1 - REPORTED_POOLED_BAND, 1 + REPORTED_POOLED_BAND)
    assert not bad, f"pooled reported std / RMS error outside 1 +- {REPORTED_POOLED_BAND}: {bad}"


@pytest.mark.slow
def test_at_the_papers_noise_the_reported_std_understates_only_cx_ry_and_kappa1(
    paper_noise_runs,
) -> None:
    ratio = pooled(reported_over_rms(paper_noise_runs))
    by_name = dict(zip(TSAI_PARAMETERS, ratio.round(3), strict=True))
    for name, r in by_name.items():
        low = PAPER_REPORTED_LOW if name in NONLINEAR else 1 - PAPER_LINEAR_BAND
        assert low <= r <= 1 + PAPER_LINEAR_BAND, (name, by_name)
