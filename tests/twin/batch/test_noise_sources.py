"""Each noise source of the batch fidelity, alone, against its stated sigma.

Every test runs one leg of the smoke room's plan (the children placed, the parent driven
and fixed) for ``TRIALS`` trials with a single source on and every other off, takes the
errors that source made (a noisy run's values minus the same trials' noise-free ones, or
an estimate minus its exact value) and checks ``sum((e / sigma)^2)``, chi-square with as
many degrees of freedom as independent errors, against its two-sided 1e-6 band: a correct
source fails one run in a million (the seeds are fixed, so a run that passes always
passes). :func:`_assert_sigma` also checks that the samples are enough for the band to
exclude a sigma scaled by 0.8 or 1.2 by more than five of the scaled statistic's standard
deviations: such a bug fails whatever the seeds.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from twin.batch.execute import BatchRun
from twin.batch.row_arrays import ALL
from twin.batch.steps import Drive, Fix, Place, PlanSession, Point, record_plan
from twin.instruments.tilt import tilt_from_orientation
from twin.scenario import load_scenario
from twin.scenario.schema import InclinometerConfig, StoppingConfig

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"

TRIALS = 2000
"""Trials of each test. 2000 draws of one error give a band of 0.85 to 1.16 on the
variance (4.9 standard errors of sqrt(2 / 2000) either side); 0.8 sigma (0.64 of the
variance) and 1.2 sigma (1.44) stand 10.5 and 6.1 of their own standard errors beyond it.
Most tests draw several errors a trial, which narrows the band further."""

FLAKE = 1e-6
"""Two-sided probability that a correct source falls outside the band."""


def _assert_sigma(errors: np.ndarray, sigma: np.ndarray | float, what: str) -> None:
    """``errors`` (any shape, independent) are N(0, sigma^2) (sigma broadcast to them)."""
    z = np.asarray(errors, dtype=float) / sigma
    n = z.size
    lo, hi = chi2.ppf(FLAKE / 2, n), chi2.ppf(1 - FLAKE / 2, n)
    # The test's power: a sigma off by 0.8 or 1.2 lands beyond the band by 5 of its sds.
    for scale in (0.8, 1.2):
        mean, sd = scale**2 * n, scale**2 * np.sqrt(2 * n)
        assert (lo - mean) / sd > 5 or (mean - hi) / sd > 5, (what, n, scale)
    stat = float(np.sum(z**2))
    assert lo < stat < hi, f"{what}: std {np.sqrt(stat / n):.4f} of the stated sigma"


@pytest.fixture(scope="module")
def smoke_plan():
    return record_plan(load_scenario(SMOKE), "paper")


@pytest.fixture(scope="module")
def leg(smoke_plan):
    """The smoke room's first CPS leg: each child driven and placed, the parent driven
    and fixed from both (the steps after the reference data)."""
    plan = smoke_plan
    first = next(i for i, s in enumerate(plan.steps) if isinstance(s, Fix))
    start = max(i for i, s in enumerate(plan.steps[:first]) if isinstance(s, Point)) + 2
    steps = plan.steps[start : first + 1]
    assert [type(s) for s in steps] == [Drive, Place, Drive, Place, Drive, Fix]
    assert steps[4].robot == plan.parent
    return dataclasses.replace(plan, steps=steps)


def _quiet(plan):
    return plan.scenario.without_noise().noise


def _with(plan, **update):
    return _quiet(plan).model_copy(update=update)


def _run(plan, noise, steps=None, trials=TRIALS):
    run = BatchRun(plan, list(range(trials)), noise=noise)
    for step in plan.steps if steps is None else steps:
        run.step(step)
    return run


def test_without_noise_the_leg_is_exact(leg):
    run = _run(leg, _quiet(leg), trials=3)
    for step in leg.steps:
        if isinstance(step, Drive):
            robot = run.robots[step.robot]
            np.testing.assert_allclose(robot.true, np.tile(step.believed, (3, 1)), atol=1e-12)
            np.testing.assert_allclose(robot.believed, robot.true, atol=1e-9)
    np.testing.assert_allclose(run.cps.parent.yaw, leg.steps[4].believed[2], atol=1e-9)


def test_a_tilted_station_levels_its_shots_with_its_tilt(smoke_plan, leg):
    # The parent on the smoke room's tilted floor patch (3 arc-minutes): noise-free, its
    # shots levelled with the station's own tilt fix it exactly where it stands.
    with PlanSession(smoke_plan.scenario, "paper") as session:
        while not session.done:
            session.answer(session.suggested())
        pose = np.array([3.0, -1.5, 0.0])
        tilted = session.truth_at(leg.parent, pose)
    tilt = np.hypot(*tilt_from_orientation(tilted.instrument2world))
    assert tilt > 5e-4
    drive = Drive(leg.parent, tilted.pose.copy(), tilted)
    run = _run(leg, _quiet(leg), steps=[*leg.steps[:4], drive, leg.steps[5]], trials=2)
    centre, _ = run.fleet.instrument(ALL)
    np.testing.assert_allclose(run.last_estimate.translation, centre, atol=1e-9)
    np.testing.assert_allclose(run.cps.parent.yaw, tilted.pose[2], atol=1e-9)


def test_the_stopping_heading_error_of_every_robot(leg):
    sigma = 0.01
    run = _run(leg, _with(leg, stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=sigma)))
    for step in leg.steps:
        if isinstance(step, Drive):
            # Each child's heading as its marker's pose measured it (exactly: the total
            # station is noise-free), the parent's as CPS fixed it.
            got = run.robots[step.robot].believed[:, 2]
            if step.robot == leg.parent:
                got = np.asarray(run.cps.parent.yaw)
            _assert_sigma(got - step.believed[2], sigma, f"{step.robot}'s heading")
            # The heading turns the robot about its origin, which stays where it was sent.
            np.testing.assert_allclose(
                run.robots[step.robot].true[:, :2], np.tile(step.believed[:2], (TRIALS, 1))
            )


def test_the_stopping_position_error_of_every_robot(leg):
    sigma = 0.02
    run = _run(leg, _with(leg, stopping=StoppingConfig(sigma_xy=sigma, sigma_yaw=0.0)))
    for step in leg.steps:
        if isinstance(step, Drive):
            robot = run.robots[step.robot]
            _assert_sigma(robot.true[:, :2] - step.believed[:2], sigma, f"{step.robot}'s stop")
            np.testing.assert_array_equal(robot.true[:, 2], step.believed[2])
            if step.robot != leg.parent:  # where its marker put it
                np.testing.assert_allclose(robot.believed, robot.true, atol=1e-9)
    # A robot driven again before anything measured it: its localisation's error (where it
    # stood against where it believed it stood) carries into the next stop, which adds its
    # own: sqrt(2) sigma.
    first = leg.steps[0]
    again = dataclasses.replace(first, believed=first.believed + np.array([0.3, 0.1, 0.0]))
    run = _run(leg, _with(leg, stopping=StoppingConfig(sigma_xy=sigma, sigma_yaw=0.0)),
               steps=[first, again])  # fmt: skip
    moved = run.robots[first.robot].true[:, :2] - again.believed[:2]
    _assert_sigma(moved, np.sqrt(2.0) * sigma, "a second stop without a fix")


def test_the_creep_of_the_standing_children_once_a_leg(leg):
    creep = 0.01
    noise = _with(leg, child_creep_m=creep)
    run = _run(leg, noise, steps=leg.steps[:4])  # the children placed
    before = {c: run.robots[c].true[:, :2].copy() for c in leg.children}
    run.step(leg.steps[4])  # the parent drives: both children creep
    moved = np.stack([run.robots[c].true[:, :2] - before[c] for c in leg.children])
    _assert_sigma(moved, creep, "creep")
    after = {c: run.robots[c].true.copy() for c in leg.children}
    run.step(leg.steps[4])  # a second drive of the same leg: no more creep
    for c in leg.children:
        np.testing.assert_array_equal(run.robots[c].true, after[c])


def _shots(plan, noise):
    """(T, 3, 3) the parent's polar shots at each child's cubes after the leg's drives."""
    run = _run(plan, noise, steps=[s for s in plan.steps if isinstance(s, Drive)])
    return {child: run.fleet.shots(child, ALL) for child in plan.children}


def _wrapped(angle: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * angle))


def test_the_inclinometer_reading_error_tilts_each_shot(leg):
    # A reading off by (d_roll, d_pitch) turns the levelled point by d x p: its zenith
    # angle by (d_roll y - d_pitch x) / hypot(x, y) (first order), of standard deviation
    # sigma whatever the direction; its distance not at all. Each shot reads its own.
    sigma = 20e-6
    tilt = InclinometerConfig(sigma=sigma, working_range=1e-3)
    exact_all, noisy_all = _shots(leg, _quiet(leg)), _shots(leg, _with(leg, inclinometer=tilt))
    for child in leg.children:
        exact, noisy = exact_all[child], noisy_all[child]
        np.testing.assert_allclose(noisy[..., 0], exact[..., 0], rtol=1e-12)
        _assert_sigma(noisy[..., 2] - exact[..., 2], sigma, f"zenith angles at {child}")


@pytest.mark.parametrize(
    ("source", "values"),
    [
        ("distance", {"distance_sigma_const": 0.002, "distance_sigma_ppm": 2000.0}),
        ("angle", {"angle_sigma": 3e-5}),
        ("pointing", {"pointing_sigma": 0.003}),
    ],
)
def test_the_total_stations_noise_on_each_shot(leg, source, values):
    # Distance: const + ppm 1e-6 d (2000 ppm: a third of the distance term at 1.7 m, so
    # that either half shows); angles: angle_sigma on each; the pointing error on the
    # prism: pointing / (d sin v) on the horizontal angle and pointing / d on the zenith.
    quiet = _quiet(leg)
    noise = quiet.model_copy(
        update={"total_station": quiet.total_station.model_copy(update=values)}
    )
    exact_all, noisy_all = _shots(leg, quiet), _shots(leg, noise)
    for child in leg.children:
        exact, noisy = exact_all[child], noisy_all[child]
        d, v = exact[..., 0], exact[..., 2]
        err = np.stack(
            [noisy[..., 0] - d, _wrapped(noisy[..., 1] - exact[..., 1]), noisy[..., 2] - v],
            axis=-1,
        )
        if source == "distance":
            sigma = np.stack(
                [values["distance_sigma_const"] + values["distance_sigma_ppm"] * 1e-6 * d], -1
            )
            np.testing.assert_allclose(err[..., 1:], 0.0, atol=1e-12)
            _assert_sigma(err[..., :1], sigma, f"distances to {child}")
        elif source == "angle":
            np.testing.assert_allclose(err[..., 0], 0.0, atol=1e-12)
            _assert_sigma(err[..., 1:], values["angle_sigma"], f"angles to {child}")
        else:
            p = values["pointing_sigma"]
            sigma = np.stack([p / (d * np.sin(v)), p / d], axis=-1)
            np.testing.assert_allclose(err[..., 0], 0.0, atol=1e-12)
            _assert_sigma(err[..., 1:], sigma, f"pointing at {child}")


def test_the_marker_assemblys_error_is_each_childs_own_for_the_whole_trial(leg):
    # noise.marker_geometry_m on each coordinate of each cube and LED, in the child's
    # body: the same at every stop of the trial (the assembly is built once).
    sigma = 0.003
    drives = [s for s in leg.steps if isinstance(s, Drive) and s.robot != leg.parent]
    exact = _run(leg, _quiet(leg), steps=drives)
    built = _run(leg, _with(leg, marker_geometry_m=sigma), steps=drives)
    leds, cubes = [], []
    for step in drives:
        c = step.robot
        leds.append(built.fleet.leds(c, ALL) - exact.fleet.leds(c, ALL))
        cubes.append(built.fleet.cubes(c, ALL) - exact.fleet.cubes(c, ALL))
    _assert_sigma(np.stack(leds), sigma, "LED positions")
    _assert_sigma(np.stack(cubes), sigma, "corner cubes")
    # The children's errors are their own; a child driven elsewhere keeps its error, turned
    # with it.
    assert abs(np.corrcoef(leds[0].ravel(), leds[1].ravel())[0, 1]) < 5 / np.sqrt(leds[0].size)
    turn = 0.4
    child = drives[0].robot
    to = dataclasses.replace(drives[0], believed=drives[0].believed + np.array([0.5, 0.2, turn]))
    before = leds[0]
    for run in (exact, built):
        run.step(to)
    after = built.fleet.leds(child, ALL) - exact.fleet.leds(child, ALL)
    c, s = np.cos(turn), np.sin(turn)
    rotated = before.copy()
    rotated[..., 0] = c * before[..., 0] - s * before[..., 1]
    rotated[..., 1] = s * before[..., 0] + c * before[..., 1]
    np.testing.assert_allclose(after, rotated, atol=1e-12)


def test_the_led_pixel_noise_is_the_detectors_and_the_centroids(smoke_plan):
    # noise.led_detection_px and noise.led_centroid_px, independent: their quadrature sum
    # (0.5 px) on each pixel coordinate of each LED found. Either left out (0.3 or 0.4 px)
    # or scaled by 0.8 (0.47 or 0.44 px) falls far outside the band of 8000 errors.
    plan = smoke_plan
    first = next(i for i, s in enumerate(plan.steps) if isinstance(s, Point))
    steps = plan.steps[: first + 1]
    reference = dataclasses.replace(plan, steps=steps)
    key = (steps[-1].dataset, steps[-1].camera, steps[-1].visit)
    pixels = []
    for noise in (_quiet(plan), _with(plan, led_detection_px=0.3, led_centroid_px=0.4)):
        run = _run(reference, noise, trials=TRIALS // 2)
        (data,) = run.datasets[key]
        pixels.append(data.pixels[0])
    assert np.isfinite(pixels[0]).all()
    _assert_sigma(pixels[1] - pixels[0], 0.5, "LED pixels")
