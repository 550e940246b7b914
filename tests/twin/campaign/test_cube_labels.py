"""The three shots at a child's corner cubes are labelled by the assembly's shape: its side
lengths and its sense of turn, seen from above (the child stands upright)."""

from __future__ import annotations

import numpy as np

from calib.rotation import rot_z
from twin.campaign.shooting import shoot_cubes
from twin.hal import TotalStation, TotalStationMeasurement
from twin.hal.readings import TiltReading
from twin.instruments.marker import MarkerAssembly
from twin.instruments.polar import cartesian2polar
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

DRAWING = MarkerAssembly().cubes_body


class _Prisms(TotalStation):
    """Locks the prism nearest the aim's direction (the automatic aim's cone)."""

    spec = TotalStationSpec()
    inclinometer = InclinometerSpec()

    def __init__(self, prisms_level: np.ndarray) -> None:
        self.prisms = prisms_level
        self.aim = np.zeros(3)

    def point(self, target_level) -> None:
        self.aim = np.asarray(target_level, dtype=float)

    def measure(self) -> TotalStationMeasurement:
        u = self.prisms / np.linalg.norm(self.prisms, axis=1, keepdims=True)
        nearest = int(np.argmax(u @ (self.aim / np.linalg.norm(self.aim))))
        return TotalStationMeasurement.from_polar(cartesian2polar(self.prisms[nearest]), 0.0)

    def read_inclination(self) -> TiltReading:
        return TiltReading(0.0, 0.0, 0.0)

    def close(self) -> None:
        pass


class _Report:
    def failure(self, kind, message, details) -> None:
        pass

    def event(self, kind, message, details) -> None:
        pass


def _built_with_two_sides_swapped() -> np.ndarray:
    """The drawing's cubes with cube 1 moved (18 mm) so that its sides to cubes 0 and 2,
    340.0 and 325.6 mm on the drawing, are 1 mm apart the other way round: a mirrored
    labelling (cubes 0 and 2 swapped) fits the side lengths 1 mm better than the true one.
    A surveying error of 3 mm a coordinate did that to a child of a simulated run (its
    sides built 334.5 and 333.3 mm): its heading came out 110 degrees off and it was lost."""
    b0, b2 = DRAWING[0, :2], DRAWING[2, :2]
    d01, d12 = np.linalg.norm(DRAWING[1] - DRAWING[0]), np.linalg.norm(DRAWING[1] - DRAWING[2])
    mean = 0.5 * (d01 + d12)
    r0, r2 = mean - 0.0005, mean + 0.0005  # |b1 - b0| and |b1 - b2| as built
    # Cube 1 on both circles, on the drawing's side of the line b0-b2.
    d = np.linalg.norm(b2 - b0)
    a = (r0**2 - r2**2 + d**2) / (2 * d)
    h = np.sqrt(r0**2 - a**2)
    e = (b2 - b0) / d
    normal = np.array([-e[1], e[0]])
    side = np.sign(normal @ (DRAWING[1, :2] - b0))
    built = DRAWING.copy()
    built[1, :2] = b0 + a * e + side * h * normal
    return built


def test_a_mirrored_labelling_is_refused_even_where_it_fits_the_sides_better():
    built = _built_with_two_sides_swapped()
    assert np.linalg.norm(built[1] - DRAWING[1]) < 0.02
    pose = rot_z(0.8), np.array([4.0, 1.5, -0.4])
    prisms = built @ pose[0].T + pose[1]
    predicted = DRAWING @ pose[0].T + pose[1]
    shots = shoot_cubes(_Prisms(prisms), predicted, 2, _Report(), DRAWING)
    assert shots is not None
    measured = np.array([s.to_cartesian() for s in shots])
    np.testing.assert_allclose(measured, prisms, atol=1e-3)  # cube k is labelled k


def test_the_labels_do_not_depend_on_the_order_the_prisms_answered():
    # Every aim lands on another prism (a parent whose heading is off): the shape labels.
    built = _built_with_two_sides_swapped()
    pose = rot_z(-2.0), np.array([-3.0, 2.0, -0.4])
    prisms = built @ pose[0].T + pose[1]
    order = [2, 0, 1]
    predicted = prisms[order]  # aiming at cube k locks cube order[k]
    shots = shoot_cubes(_Prisms(prisms), predicted, 2, _Report(), DRAWING)
    assert shots is not None
    measured = np.array([s.to_cartesian() for s in shots])
    np.testing.assert_allclose(measured, prisms, atol=1e-3)


def test_cubes_standing_one_above_another_are_labelled_by_their_sides():
    # A triangle in a vertical plane shows no sense of turn from above: its sides label it.
    upright = np.array([[0.1, 0.0, 1.4], [-0.1, 0.0, 1.8], [0.0, 0.0, 1.1]])
    pose = rot_z(0.5), np.array([3.0, -1.0, -0.4])
    prisms = upright @ pose[0].T + pose[1]
    shots = shoot_cubes(_Prisms(prisms), prisms, 2, _Report(), upright)
    assert shots is not None
    measured = np.array([s.to_cartesian() for s in shots])
    np.testing.assert_allclose(measured, prisms, atol=1e-3)
