"""What the campaign derives and records beside the devices' readings (topics
``/campaign/...``): each is a frozen dataclass with a timestamp, in SI units and W."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

STAGE = "/campaign/stage"
PARENT_FIX = "/campaign/parent_fix"
POINT = "/campaign/point"
CALIBRATION = "/campaign/calibration"
FAILURE = "/campaign/failure"
EVENT = "/campaign/event"
SKIPPED = "/campaign/skipped_visit"
DATASET = "/campaign/dataset"
CHILD_PLACED = "/campaign/child_placed"
CONTROL_SIGHTING = "/campaign/control_sighting"


@dataclass(frozen=True)
class Stage:
    """A stage of the campaign starts.

    Attributes:
        timestamp: s. stage: ``reference``, ``travel``, ``station``, ``done``.
        camera: the camera concerned ("" if none). visit: 1-based visit number of the
            camera (0 for a reference data set or travel). detail: words.
    """

    timestamp: float
    stage: str
    camera: str = ""
    visit: int = 0
    detail: str = ""


@dataclass(frozen=True)
class ParentFix:
    """The parent's pose in W after a CPS step (or at its first station).

    Attributes:
        timestamp: s. index: station number (0 = the first, which defines W).
        yaw: rad. translation: (3,) instrument centre in W, m. covariance: (4, 4) of
            (yaw, x, y, z). distance_travelled: the parent's travel so far, m.
        children: the children the fix was solved from, in the order measured (none at
            the first station).
        children_level: (N, 3) those children's reference points as measured from this
            station, in its levelled frame, m (what a global adjustment needs).
        children_covariance: (N, 3, 3) their covariances, m^2.
    """

    timestamp: float
    index: int
    yaw: float
    translation: NDArray[np.float64]
    covariance: NDArray[np.float64]
    distance_travelled: float
    children: tuple[str, ...] = ()
    children_level: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    children_covariance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3, 3)))


@dataclass(frozen=True)
class ChildPlaced:
    """A child measured from the standing parent and placed in the CPS state (it moved, or
    it was found moved).

    Attributes:
        timestamp: s. child: name.
        point_level: (3,) its reference point in the parent's levelled frame, m.
        covariance: (3, 3) of ``point_level``, m^2.
        world: (3,) its reference point in W, from the parent's estimate, m.
    """

    timestamp: float
    child: str
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    world: NDArray[np.float64]


@dataclass(frozen=True)
class DataPoint:
    """One stop of a child in a camera's view: its LEDs in 3D and in the image.

    Attributes:
        timestamp: s. dataset: ``reference`` or ``visit``. camera: name. visit: the
            camera's visit number (0 for a reference data set). child: name.
        leds_world: (N_led, 3) LED positions in W from the total station and CPS, m.
        pixels: (N_led, 2) where the camera found them, px.
        child_xy: (2,) the child's reference point in W, m.
        leds_covariance: (3 N_led, 3 N_led) joint covariance of ``leds_world`` from the
            measured marker pose (shared by the LEDs of one stop), without the parent's
            pose error (common to a whole station), m^2; empty when unknown.
        partial: whether the stop's plan takes a point from the LEDs the camera finds where
            it does not find them all (:attr:`twin.campaign.strategy.StopPlan.partial`);
            else such a stop gives no point.
        survey_loading: (3 N_led, M) where the LEDs truly stand off ``leds_world`` for
            the marker assembly's surveying error, m, per unit of an (M,) standard normal
            vector z that every stop of this child shares (they stand at ``leds_world +
            L z``: :func:`twin.instruments.marker_pose.survey_loading`): two stops s, t of
            the child add ``L_s L_t^T`` to their joint covariance. Empty when the assembly
            is known exactly.
    """

    timestamp: float
    dataset: str
    camera: str
    visit: int
    child: str
    leds_world: NDArray[np.float64]
    pixels: NDArray[np.float64]
    child_xy: NDArray[np.float64]
    leds_covariance: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))
    partial: bool = False
    survey_loading: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))


@dataclass(frozen=True)
class CalibrationRecord:
    """A camera calibrated from one visit's data.

    Attributes:
        timestamp: s. camera, visit: which calibration. station: (2,) planned station, m.
        distance_travelled: the parent's travel when the data were taken, m.
        points: number of LED points used.
        parameters: Tsai's parameters by name, SI (``calib.tsai`` names).
        std: their standard deviations.
        camera_model: the calibrated camera as ``calib.io.camera_to_dict`` writes it.
        sigma_px: residual standard deviation, px.
    """

    timestamp: float
    camera: str
    visit: int
    station: NDArray[np.float64]
    distance_travelled: float
    points: int
    parameters: dict[str, float]
    std: dict[str, float]
    camera_model: dict[str, Any] = field(default_factory=dict)
    sigma_px: float = float("nan")


@dataclass(frozen=True)
class Occurrence:
    """Something that happened in the campaign that is not a measurement.

    Attributes:
        timestamp: s. kind: a short name (``lost_lock``, ``child_turned``...).
        message: words. robot, camera: concerned ("" if none).
        details: plain values.
    """

    timestamp: float
    kind: str
    message: str = ""
    robot: str = ""
    camera: str = ""
    details: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Failure(Occurrence):
    """Something went wrong and the campaign went on (``lost_lock``, ``point_skipped``,
    ``child_moved``...)."""


@dataclass(frozen=True)
class CampaignEvent(Occurrence):
    """Something the campaign did that is not a fault: a child turned to show its prisms,
    the parent stepped aside to see the children, a prism aimed at again from the others."""


@dataclass(frozen=True)
class SkippedVisit:
    """A visit that yielded no calibration.

    Attributes:
        timestamp: s. camera, visit: which. station: (2,) m. reason: a short name
        (``station_unreachable``, ``too_few_points``). message: words.
    """

    timestamp: float
    camera: str
    visit: int
    station: NDArray[np.float64]
    reason: str
    message: str = ""


@dataclass(frozen=True)
class DataSet:
    """A data set is complete: the first ``points`` LED points of its data points (in the
    order recorded) are the set.

    Attributes:
        timestamp: s. dataset: ``reference`` or ``visit``. camera, visit: which.
        points: LED points in the set.
    """

    timestamp: float
    dataset: str
    camera: str
    visit: int
    points: int


@dataclass(frozen=True)
class ControlSighting:
    """A control point (a prism left in place, or a surveyed mark) measured from the
    parent's current station.

    Attributes:
        timestamp: s. name: the control point's name.
        point_level: (3,) the point in the parent's levelled frame, m.
        covariance: (3, 3) of ``point_level``, m^2.
        world: (3,) the point in W from the parent's estimate, m.
    """

    timestamp: float
    name: str
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    world: NDArray[np.float64]
