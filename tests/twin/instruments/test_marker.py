"""Marker assembly: geometry checks, pose from three cubes, LED positions and covariance."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from twin.instruments.consistency import chi2_threshold
from twin.instruments.marker import MarkerAssembly
from twin.instruments.marker_pose import (
    cube_centroid_batch,
    fit_marker_pose,
    led_positions,
    marker_consistency_chi2,
    survey_covariance,
    survey_layout,
    survey_loading,
)
from twin.instruments.noise import cartesian_covariance
from twin.instruments.polar import cartesian2polar, polar2cartesian
from twin.instruments.shot import measure_points
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

MARKER = MarkerAssembly()


def test_default_geometry_looks_like_the_paper():
    leds, cubes = MARKER.leds_body, MARKER.cubes_body
    assert leds.shape == (4, 3)
    assert cubes.shape == (3, 3)
    assert len(np.unique(leds[:, 2])) == 4  # four different heights
    assert 0.8 <= np.ptp(leds[:, 2]) <= 1.2  # spread over about 1 m
    sides = np.linalg.norm(cubes - np.roll(cubes, 1, axis=0), axis=1)
    assert sides.min() > 0.2  # cubes far enough apart
    np.testing.assert_allclose(MARKER.reference_body, cubes.mean(axis=0))
    with pytest.raises(ValueError, match="read-only"):
        MARKER.cubes_body[0, 0] = 1.0  # read-only


def test_marker_rejects_bad_geometry():
    with pytest.raises(ValueError, match="collinear"):
        MarkerAssembly(cubes_body=np.array([[0, 0, 1.0], [0.1, 0, 1.0], [0.2, 0, 1.0]]))
    with pytest.raises(ValueError, match=r"cubes_body must have shape \(3, 3\)"):
        MarkerAssembly(cubes_body=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="leds_body"):
        MarkerAssembly(leds_body=np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        MarkerAssembly(leds_body=np.full((4, 3), np.nan))


@settings(max_examples=50, deadline=None)
@given(
    st.tuples(st.floats(-np.pi, np.pi), st.floats(-0.3, 0.3), st.floats(-0.3, 0.3)),
    st.tuples(st.floats(-100, 100), st.floats(-100, 100), st.floats(-2, 2)),
)
def test_noise_free_pose_and_leds_are_exact(angles, translation):
    rot = Rotation.from_euler("ZYX", angles).as_matrix()
    t = np.array(translation)
    cubes = MARKER.cubes_body @ rot.T + t
    pose = fit_marker_pose(cubes, MARKER)
    np.testing.assert_allclose(pose.rotation, rot, atol=1e-9)
    np.testing.assert_allclose(pose.translation, t, atol=1e-9)
    assert pose.rms_residual < 1e-9
    leds, cov = led_positions(pose, MARKER)
    np.testing.assert_allclose(leds, MARKER.leds_body @ rot.T + t, atol=1e-9)
    assert np.all(cov == 0)


def test_led_covariance_matches_monte_carlo():
    spec, incl = TotalStationSpec(), InclinometerSpec()
    rng = np.random.default_rng(11)
    rot = Rotation.from_euler("z", 0.4).as_matrix()
    t = np.array([15.0, 6.0, -0.75])  # a child 16 m away, floor 0.75 m below the instrument
    cubes = MARKER.cubes_body @ rot.T + t
    leds_true = MARKER.leds_body @ rot.T + t
    n = 3000
    polar, _ = measure_points(np.tile(cubes, (n, 1, 1)), 0.0, 0.0, spec, incl, rng)
    measured = polar2cartesian(polar)
    nees = np.empty(n)
    for i in range(n):
        pose = fit_marker_pose(measured[i], MARKER, cartesian_covariance(polar[i], spec, incl))
        leds, cov = led_positions(pose, MARKER)
        e = (leds - leds_true)[3]  # the lowest LED, 1.05 m below the cubes
        nees[i] = e @ np.linalg.solve(cov[9:12, 9:12], e)
    # 3 degrees of freedom: mean 3, standard error sqrt(6 / n) = 0.045
    assert nees.mean() == pytest.approx(3.0, abs=0.2)


def test_survey_covariance_matches_monte_carlo_of_a_surveyed_assembly():
    # Each coordinate of the cubes and LEDs as built is off the drawing by 3 mm (std); the
    # pose fitted to the built cubes with the drawing places the LEDs off by what
    # survey_loading predicts, at any heading (here 0.7 rad), shared by the child's stops.
    sigma, n = 0.003, 4000
    marker = MarkerAssembly(survey_sigma=sigma)
    rng = np.random.default_rng(12)
    rot = Rotation.from_euler("z", 0.7).as_matrix()
    t = np.array([3.0, 1.0, -0.2])
    errors = np.empty((n, 3 * len(MARKER.leds_body)))
    for i in range(n):
        cubes = MARKER.cubes_body + sigma * rng.standard_normal((3, 3))
        leds = MARKER.leds_body + sigma * rng.standard_normal(MARKER.leds_body.shape)
        pose = fit_marker_pose(cubes @ rot.T + t, MARKER)
        errors[i] = (pose.transform(MARKER.leds_body) - (leds @ rot.T + t)).ravel()
    loading = survey_loading(marker, rot)
    predicted = loading @ loading.T
    # A variance from n samples has a relative standard error of sqrt(2 / n) = 2.2 %.
    np.testing.assert_allclose(np.cov(errors.T).diagonal(), predicted.diagonal(), rtol=0.1)
    # The top LED's error is several times the surveying error: the cubes' small triangle
    # turns the whole mast.
    assert np.sqrt(predicted.diagonal()).max() > 4 * sigma
    np.testing.assert_allclose(
        survey_covariance(marker),
        survey_loading(marker, np.eye(3)) @ survey_loading(marker, np.eye(3)).T,
        atol=1e-18,
    )


def test_survey_loading_turns_with_the_child_and_vanishes_for_an_exact_assembly():
    marker = MarkerAssembly(survey_sigma=0.001)
    rots = Rotation.from_euler("z", [[0.3], [2.0]]).as_matrix()
    both = survey_loading(marker, rots)
    assert both.shape == (2, 12, 12)
    for k in range(2):
        np.testing.assert_allclose(both[k], survey_loading(marker, rots[k]), atol=1e-15)
    # Turning the child turns its LEDs' errors: the covariance's trace stays.
    assert np.trace(both[0] @ both[0].T) == pytest.approx(np.trace(both[1] @ both[1].T))
    assert not survey_loading(MARKER, rots[0]).any()


def test_survey_layout_places_each_stop_on_its_childs_columns():
    a, b = np.full((6, 2), 1.0), np.full((3, 2), 2.0)
    out = survey_layout(["c2", "c1", "c2"], [a, b, a], k=6)
    assert out.shape == (18, 4)
    np.testing.assert_array_equal(out[0:6, 2:4], a)  # c2: the second child by name
    np.testing.assert_array_equal(out[6:9, 0:2], b)  # a stop of one LED: its rows first
    assert not out[9:12].any()
    np.testing.assert_array_equal(out[12:18, 2:4], a)
    assert out[:, :2].sum() == b.sum()
    assert survey_layout(["c1"], [np.zeros((0, 0))], k=6) is None


def test_centroid_and_its_covariance():
    cubes = MARKER.cubes_body + np.array([10.0, 0.0, 0.0])
    cov = cartesian_covariance(cartesian2polar(cubes), TotalStationSpec())
    point, point_cov = cube_centroid_batch(cubes, cov)
    np.testing.assert_allclose(point, cubes.mean(axis=0))
    np.testing.assert_allclose(point_cov, cov.sum(axis=0) / 9, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("order", [(0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)])
def test_mislabelled_cubes_show_in_the_residual(order):
    # The default triangle is scalene: no wrong labelling fits (a wrong prism lock shows
    # as a centimetre residual, not millimetres).
    cubes = MARKER.cubes_body + np.array([10.0, 0.0, 0.0])
    assert fit_marker_pose(cubes[list(order)], MARKER).rms_residual > 0.008


def test_fit_chi2_follows_chi_square_3_and_matches_the_side_lengths():
    # Cubes measured from a tilted instrument with the Table I noise, 6-14 m away.
    spec, incl = TotalStationSpec(), InclinometerSpec()
    rng = np.random.default_rng(11)
    n = 400
    offsets = np.stack([rng.uniform(6, 14, n), rng.uniform(-3, 3, n), np.full(n, -0.75)], -1)
    cubes = MARKER.cubes_body[None] + offsets[:, None, :]
    polar, _ = measure_points(cubes, 30e-6, -20e-6, spec, incl, rng)
    measured = polar2cartesian(polar)
    cov = cartesian_covariance(polar, spec, incl)
    fit = np.array([fit_marker_pose(m, MARKER, c).chi2 for m, c in zip(measured, cov, strict=True)])
    sides = marker_consistency_chi2(measured, cov, MARKER)
    # equal to first order; they differ at second order (2 mm range noise on a 0.3 m
    # triangle: about 1 %, i.e. a few % of chi2)
    np.testing.assert_allclose(sides, fit, rtol=0.1, atol=0.05)
    assert fit.mean() == pytest.approx(3.0, abs=0.4)  # chi-square, 3 dof: SE 0.12
    assert np.all(fit < chi2_threshold(3, 1e-4))
    # a wrong cube (cube 1 locked for the shot at cube 0) is far beyond the threshold
    wrong = measured[0][[1, 1, 2]]
    wrong_cov = cov[0][[1, 1, 2]]
    assert fit_marker_pose(wrong, MARKER, wrong_cov).chi2 > 1e3 * chi2_threshold(3, 1e-4)
    assert marker_consistency_chi2(wrong, wrong_cov, MARKER) > 1e3 * chi2_threshold(3, 1e-4)
    # no covariance: no chi2
    assert fit_marker_pose(measured[0], MARKER).chi2 is None


def test_pose_bad_input():
    good = MARKER.cubes_body + np.array([10.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"shape \(3, 3\)"):
        fit_marker_pose(good[:2], MARKER)
    bad = good.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        fit_marker_pose(bad, MARKER)
    with pytest.raises(ValueError, match="covariance"):
        fit_marker_pose(good, MARKER, np.eye(4))
    with pytest.raises(ValueError, match="symmetric"):
        fit_marker_pose(good, MARKER, np.triu(np.ones((9, 9))))
