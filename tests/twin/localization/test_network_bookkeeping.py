"""The network's bookkeeping, value by value: what :class:`NetworkBuilder` adds for each
measurement (a stand's creep once per fix since it was placed, a control point's world
coordinates, an LED stop turned into its station's levelled frame), what the adjustment
counts (the unknowns, the residuals and so the degrees of freedom, worked out by hand) and
the covariances it reports (the inverse of the normal equations of residuals written here
from the module's text, by finite differences)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.rotation import rot_z
from tests.twin.localization.network_loop import Noise, make_loop
from twin.localization.adjustment import adjust_network
from twin.localization.network import Network, NetworkBuilder, PointSighting

CREEP = 0.01


def _spd(rng: np.random.Generator, scale: float) -> np.ndarray:
    a = rng.normal(size=(3, 3))
    return scale**2 * (a @ a.T + np.eye(3))


def test_a_stands_later_sightings_carry_the_creep_of_each_fix_since_it_was_placed():
    rng = np.random.default_rng(1)
    cov = _spd(rng, 1e-3)
    b = NetworkBuilder(child_creep_m=CREEP)
    b.station(0.0, np.zeros(3))
    b.stand("c1", [1.0, 0.0, 0.0], cov, [1.0, 0.0, 0.0])  # stand 0, placed at station 0
    b.station(0.1, [0.5, 0.0, 0.0])
    b.sight_child("c1", [0.5, 0.0, 0.0], cov)  # one fix since placed
    b.stand("c2", [2.0, 1.0, 0.0], cov, [2.0, 1.0, 0.0])  # stand 1, placed at station 1
    b.station(0.2, [1.0, 0.0, 0.0])
    b.sight_child("c1", [0.0, 0.0, 0.0], cov)  # two fixes
    b.sight_child("c2", [1.0, 1.0, 0.0], cov)  # one fix
    b.stand("c1", [1.5, 0.0, 0.0], cov, [2.5, 0.0, 0.0])  # stand 2: c1 placed again
    b.station(0.3, [2.0, 0.0, 0.0])
    b.sight_child("c1", [0.5, 0.0, 0.0], cov)  # the new stand: one fix
    net = b.build()
    assert [(s.station, s.target) for s in net.point_sightings] == [
        (0, 0),
        (1, 0),
        (1, 1),
        (2, 0),
        (2, 1),
        (2, 2),
        (3, 2),
    ]
    horizontal = np.diag([1.0, 1.0, 0.0])
    fixes = [0, 1, 0, 2, 1, 0, 1]
    for s, n in zip(net.point_sightings, fixes, strict=True):
        assert_allclose(s.covariance, cov + n * CREEP**2 * horizontal, rtol=0, atol=1e-18)
    assert net.sightings_of_targets().tolist() == [3, 2, 2]
    assert not net.control_targets.any()
    assert net.target_labels == ("stand of c1", "stand of c2", "stand of c1")


def test_a_control_point_is_placed_from_its_first_sighting_unless_surveyed():
    b = NetworkBuilder(surveyed={"mark": np.array([5.0, 6.0, 0.5])})
    b.station(0.0, np.zeros(3))
    b.station(0.5, np.array([1.0, 2.0, 0.1]))
    level = np.array([3.0, -1.0, 0.2])
    b.sight_control("prism", level, np.eye(3) * 1e-6)
    b.sight_control("mark", [1.0, 1.0, 0.0], np.eye(3) * 1e-6)
    b.sight_control("once", [2.0, 0.0, 0.0], np.eye(3) * 1e-6)
    b.station(1.0, np.array([2.0, 3.0, 0.0]))
    b.sight_control("prism", [0.5, 0.5, 0.0], np.eye(3) * 1e-6)
    net = b.build()
    c, s = np.cos(0.5), np.sin(0.5)
    prism = np.array([1.0 + c * 3.0 + s * 1.0, 2.0 + s * 3.0 - c * 1.0, 0.3])
    assert_allclose(net.targets[0], prism, atol=1e-15)
    assert_allclose(net.targets[1], [5.0, 6.0, 0.5])
    assert net.known_targets.tolist() == [False, True, False]
    assert net.control_targets.tolist() == [True, True, True]
    assert net.sightings_of_targets().tolist() == [2, 1, 1]
    assert [(s.station, s.target) for s in net.point_sightings] == [(1, 0), (1, 1), (1, 2), (2, 0)]
    # Measured twice beyond CPS: the prism from two stations, the surveyed mark once; not
    # the point seen once.
    assert net.redundancy() == [
        "control point prism from stations [1, 2]",
        "control point mark (surveyed)",
    ]


def test_a_control_point_seen_twice_from_one_station_is_no_redundancy():
    b = NetworkBuilder()
    b.station(0.0, np.zeros(3))
    b.station(0.5, np.ones(3))
    for _ in range(2):
        b.sight_control("prism", [1.0, 0.0, 0.0], np.eye(3) * 1e-6)
    assert b.build().sightings_of_targets().tolist() == [2]
    assert b.build().redundancy() == []


def test_an_led_stop_is_turned_into_its_stations_levelled_frame():
    rng = np.random.default_rng(2)
    b = NetworkBuilder()
    b.station(0.0, np.zeros(3))
    yaw, t = 0.7, np.array([2.0, -1.0, 0.05])
    b.station(yaw, t)
    b.camera(np.arange(11.0), (320, 240), 0.2, "cam")
    world = rng.normal(size=(4, 3))
    a = rng.normal(size=(12, 12))
    cov = 1e-6 * (a @ a.T)
    survey = rng.normal(size=(12, 5)) * 1e-3
    pixels = rng.uniform(0, 300, (4, 2))
    b.stop(1, 0, world, cov, pixels, "c1", survey)
    (s,) = b.build().led_sightings
    r = rot_z(yaw)
    assert_allclose(s.leds_level @ r.T + t, world, atol=1e-14)
    turn = np.kron(np.eye(4), r)
    # Level = R^T (world - t): the covariance and the loadings turn with it.
    assert_allclose(turn @ s.covariance_level @ turn.T, cov, atol=1e-20)
    assert_allclose(turn @ s.survey_level, survey, atol=1e-16)
    assert (s.station, s.camera, s.child) == (1, 0, "c1")
    np.testing.assert_array_equal(s.pixels, pixels)


# -- a small network of points, adjusted -----------------------------------------------------

STATIONS = np.array([[0.0, 0.0, 0.0, 0.0], [0.1, 4.0, 0.5, 0.02], [0.3, 8.0, 1.0, -0.01]])
TARGETS = np.array(
    [
        [2.0, 1.5, 0.3],  # 0: a stand seen from stations 0 and 1
        [2.5, -1.5, 0.4],  # 1: a stand seen from stations 0 and 1
        [6.0, 2.5, 0.3],  # 2: a stand seen from stations 1 and 2
        [6.5, -1.0, 0.5],  # 3: a stand seen from stations 1 and 2
        [10.0, 3.0, 1.0],  # 4: a surveyed control point seen from station 2
        [11.0, -2.0, 0.8],  # 5: a control point seen once, from station 2
        [0.0, 9.0, 0.0],  # 6: a target never seen
    ]
)
SEEN = [(0, 0), (1, 0), (0, 1), (1, 1), (1, 2), (2, 2), (1, 3), (2, 3), (2, 4), (2, 5)]
KNOWN = np.array([False, False, False, False, True, False, False])
CONTROL = np.array([False, False, False, False, True, True, False])
FREE = [0, 1, 2, 3, 5]
"""The targets that are unknowns: measured, and not surveyed."""


def _level(station: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rz(yaw)^T (X - t), the module's model of a sighting."""
    return rot_z(station[0]).T @ (target - station[1:])


def _points_network(rng: np.random.Generator, noise: bool) -> Network:
    covs = [_spd(rng, 2e-3) for _ in SEEN]
    sightings = []
    for (k, m), cov in zip(SEEN, covs, strict=True):
        z = _level(STATIONS[k], TARGETS[m])
        if noise:
            z = z + np.linalg.cholesky(cov) @ rng.standard_normal(3)
        sightings.append(PointSighting(k, m, z, cov))
    start_stations = STATIONS.copy()
    start_stations[1:, 0] += 2e-3
    start_stations[1:, 1:] += 0.02
    start_targets = TARGETS.copy()
    start_targets[FREE] += 0.03
    return Network(
        stations=start_stations,
        targets=start_targets,
        known_targets=KNOWN,
        control_targets=CONTROL,
        cameras=np.zeros((0, 11)),
        image_sizes=np.zeros((0, 2), dtype=np.int64),
        pixel_noise_px=np.zeros(0),
        point_sightings=tuple(sightings),
        led_sightings=(),
    )


def _unknowns(x: np.ndarray, net: Network) -> tuple[np.ndarray, np.ndarray]:
    """Stations 1, 2 (4 each), then the free targets (3 each), from a vector."""
    stations = net.stations.copy()
    stations[1:] = x[:8].reshape(2, 4)
    targets = net.targets.copy()
    targets[FREE] = x[8:].reshape(-1, 3)
    return stations, targets


def _whitened(x: np.ndarray, net: Network) -> np.ndarray:
    """Each sighting's residual whitened by its own covariance (L^-1 r, C = L L^T)."""
    stations, targets = _unknowns(x, net)
    out = []
    for s in net.point_sightings:
        r = _level(stations[s.station], targets[s.target]) - s.point_level
        out.append(np.linalg.solve(np.linalg.cholesky(s.covariance), r))
    return np.concatenate(out)


def _jacobian(x: np.ndarray, net: Network) -> np.ndarray:
    step = 1e-6
    cols = []
    for i in range(len(x)):
        dx = np.zeros_like(x)
        dx[i] = step
        cols.append((_whitened(x + dx, net) - _whitened(x - dx, net)) / (2 * step))
    return np.column_stack(cols)


def _vector(stations: np.ndarray, targets: np.ndarray) -> np.ndarray:
    return np.concatenate([stations[1:].ravel(), targets[FREE].ravel()])


def test_the_degrees_of_freedom_of_a_small_network_by_hand():
    # Ten sightings of three coordinates: 30 residuals. Unknowns: stations 1 and 2 (4
    # each; station 0 is W) and the five targets measured and not surveyed (3 each): 23.
    # The surveyed point is no unknown; the point seen once adds 3 residuals and 3
    # unknowns; the target never seen adds nothing. 30 - 23 = 7.
    adjusted = adjust_network(_points_network(np.random.default_rng(3), False))
    assert adjusted.dof == 7
    assert adjusted.redundancy == ("target 4 (surveyed)",)  # not the point seen once
    assert_allclose(adjusted.stations, STATIONS, atol=1e-9)
    assert_allclose(adjusted.targets[FREE], TARGETS[FREE], atol=1e-9)
    # The target never seen keeps its start; the surveyed one its coordinates.
    assert_allclose(adjusted.targets[[4, 6]], TARGETS[[4, 6]])


def test_the_loops_degrees_of_freedom_by_hand():
    # make_loop: 14 stations (13 unknown, 4 each), 26 stands seen twice, a control point
    # seen from two stations (27 targets of 3), one camera (11) or one a visit (22), two
    # visits of 14 stops of 4 LEDs (112 LEDs, 2 pixels each).
    shared = make_loop(np.random.default_rng(4), Noise(), control=True)
    assert len(shared.network.stations) == 14
    residuals = 3 * (2 * 26 + 2) + 2 * 112
    unknowns = 4 * 13 + 3 * 27
    assert adjust_network(shared.network).dof == residuals - unknowns - 11 == 242
    per_visit = make_loop(np.random.default_rng(4), Noise(), control=True, cameras="per_visit")
    assert adjust_network(per_visit.network).dof == residuals - unknowns - 22
    # Surveyed, the control point is no unknown: 3 more.
    net = shared.network
    surveyed = dataclasses.replace(net, known_targets=net.control_targets.copy())
    assert adjust_network(surveyed).dof == residuals - unknowns - 11 + 3
    # Each child's survey error: one unknown and one prior residual a component.
    rng = np.random.default_rng(5)
    sightings = tuple(
        dataclasses.replace(s, child="c1", survey_level=rng.normal(0, 1e-3, (12, 6)))
        for s in net.led_sightings
    )
    loaded = dataclasses.replace(net, led_sightings=sightings)
    assert adjust_network(loaded).dof == residuals - unknowns - 11


@pytest.fixture(scope="module")
def noisy_points():
    net = _points_network(np.random.default_rng(6), True)
    return net, adjust_network(net)


def test_the_solution_minimises_the_whitened_residuals(noisy_points):
    net, adjusted = noisy_points
    x = _vector(adjusted.stations, adjusted.targets)
    r = _whitened(x, net)
    assert adjusted.chi2 == pytest.approx(float(r @ r), rel=1e-9)
    assert adjusted.chi2 > 0.1  # the noise left something to minimise
    jac = _jacobian(x, net)
    # A minimum: the gradient vanishes (in units of the parameters' own standard errors).
    cov = np.linalg.inv(jac.T @ jac)
    assert np.abs((jac.T @ r) * np.sqrt(np.diag(cov))).max() < 1e-6


def test_the_station_covariances_are_the_inverse_normal_equations(noisy_points):
    net, adjusted = noisy_points
    x = _vector(adjusted.stations, adjusted.targets)
    jac = _jacobian(x, net)
    cov = np.linalg.inv(jac.T @ jac)
    assert adjusted.station_covariances.shape == (3, 4, 4)
    np.testing.assert_array_equal(adjusted.station_covariances[0], 0.0)
    for k in (1, 2):
        block = cov[4 * (k - 1) : 4 * k, 4 * (k - 1) : 4 * k]
        std = np.sqrt(np.diag(block))
        assert_allclose(
            adjusted.station_covariances[k] / np.outer(std, std),
            block / np.outer(std, std),
            atol=1e-6,
        )
        assert_allclose(np.diag(adjusted.station_covariances[k]), np.diag(block), rtol=1e-5)


def test_the_loops_covariances_are_the_inverse_normal_equations():
    # The loop (one camera, a control point, each child's survey error): the camera's,
    # the stations' and the survey errors' blocks of (J^T J)^-1, J the whitened residuals'
    # central differences at the solution.
    from twin.localization.adjustment import _Problem

    loop = make_loop(np.random.default_rng(7), Noise(), control=True)
    rng = np.random.default_rng(8)
    sightings = tuple(
        dataclasses.replace(
            s, child=f"c{k % 2}", survey_level=rng.normal(0, 1e-3, (12, 3 + 2 * (k % 2)))
        )
        for k, s in enumerate(loop.network.led_sightings)
    )
    net = dataclasses.replace(loop.network, led_sightings=sightings)
    adjusted = adjust_network(net)
    problem = _Problem(net)
    layout = problem.layout
    x = layout.pack(dataclasses.replace(net, stations=adjusted.stations, targets=adjusted.targets))
    x[layout.camera_start : layout.camera_end] = adjusted.cameras.ravel()
    for child, z in adjusted.surveys.items():
        x[layout.survey_column[child] : layout.survey_column[child] + len(z)] = z
    scale = np.maximum(np.abs(x), 1.0) * 1e-6
    cols = []
    for i in range(len(x)):
        dx = np.zeros_like(x)
        dx[i] = scale[i]
        plus, _ = problem.residuals_and_jacobian(x + dx)
        minus, _ = problem.residuals_and_jacobian(x - dx)
        cols.append((plus - minus) / (2 * scale[i]))
    jac = np.column_stack(cols)
    cov = np.linalg.inv(jac.T @ jac)

    def same(got: np.ndarray, idx: np.ndarray) -> None:
        want = cov[np.ix_(idx, idx)]
        std = np.sqrt(np.diag(want))
        assert_allclose(np.sqrt(np.diag(got)), std, rtol=1e-4)
        assert_allclose(got / np.outer(std, std), want / np.outer(std, std), atol=1e-4)

    same(adjusted.camera_covariances[0], layout.camera_start + np.arange(11))
    for k in range(1, len(net.stations)):
        same(adjusted.station_covariances[k], 4 * (k - 1) + np.arange(4))
    assert set(adjusted.survey_covariances) == {"c0", "c1"}
    for child, block in adjusted.survey_covariances.items():
        same(block, layout.survey_column[child] + np.arange(layout.survey_width[child]))
