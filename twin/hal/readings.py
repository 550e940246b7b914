"""What the devices report: frozen, timestamped records in SI units.

The total station's shot and the inclination reading are the instrument records of
:mod:`twin.instruments` (:class:`TotalStationMeasurement`, :class:`TiltReading`); this module
adds the others. Times are seconds on the rig's clock; positions in metres; angles in rad;
pixels in the OpenCV convention ((0, 0) is the centre of the top-left pixel).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.instruments.polar import TotalStationMeasurement
from twin.instruments.tilt import TiltReading

__all__ = [
    "CameraImage",
    "DriveResult",
    "DriveStatus",
    "Event",
    "LedObservation",
    "LedSwitch",
    "OdometryReading",
    "TiltReading",
    "TotalStationMeasurement",
]


def _frozen_array(value: Any, shape: tuple[int, ...] | None, name: str) -> NDArray:
    a = np.array(value, dtype=float)
    if shape is not None and a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class OdometryReading:
    """A mobile base's own estimate of its pose (wheel odometry, reset by pose fixes).

    Attributes:
        robot: the base's name.
        timestamp: s.
        x, y: position of the body origin in the frame the base was last set in, m.
        yaw: heading, rad.
    """

    robot: str
    timestamp: float
    x: float
    y: float
    yaw: float

    def __post_init__(self) -> None:
        if not np.all(np.isfinite((self.timestamp, self.x, self.y, self.yaw))):
            raise ValueError(f"odometry of {self.robot!r} must be finite, got {self}")

    @property
    def pose(self) -> NDArray[np.float64]:
        """(3,) (x m, y m, yaw rad)."""
        return np.array([self.x, self.y, self.yaw])


class DriveStatus(enum.Enum):
    """How a drive ended."""

    REACHED = "reached"
    """The base stopped at the goal, within its tolerance."""
    BLOCKED = "blocked"
    """The base found its way blocked and stopped short."""
    COLLISION = "collision"
    """The base touched something and stopped."""
    TIMEOUT = "timeout"
    """The base did not arrive in the time allowed and stopped."""
    FELL_OVER = "fell_over"
    """The base tipped over; it cannot go on without help."""


@dataclass(frozen=True)
class DriveResult:
    """The end of one drive: where the base believes it stopped and why.

    Attributes:
        robot: the base's name.
        timestamp: when it stopped, s.
        goal: (3,) the goal (x m, y m, yaw rad; yaw NaN when none was asked).
        status: how the drive ended.
        odometry: the base's pose estimate when it stopped.
        duration: time the drive took, s.
        message: a note from the base ("" if none).
    """

    robot: str
    timestamp: float
    goal: NDArray[np.float64]
    status: DriveStatus
    odometry: OdometryReading
    duration: float
    message: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "goal", _frozen_array(self.goal, (3,), "goal"))
        if not isinstance(self.status, DriveStatus):
            raise ValueError(f"status must be a DriveStatus, got {self.status!r}")

    @property
    def reached(self) -> bool:
        """Whether the base arrived."""
        return self.status is DriveStatus.REACHED


@dataclass(frozen=True)
class LedSwitch:
    """The LEDs of a child were switched.

    Attributes:
        child: the child's name. timestamp: s. on: one flag per LED, lowest first.
    """

    child: str
    timestamp: float
    on: tuple[bool, ...]


@dataclass(frozen=True, eq=False)
class CameraImage:
    """One image from a camera.

    Attributes:
        camera: the camera's name. timestamp: s.
        image: (H, W) or (H, W, 3) array in DN (uint8 or uint16), read-only.
    """

    camera: str
    timestamp: float
    image: NDArray

    def __post_init__(self) -> None:
        a = np.array(self.image)
        if a.ndim not in (2, 3) or a.size == 0:
            raise ValueError(f"image of {self.camera!r} must be (H, W) or (H, W, 3), got {a.shape}")
        a.setflags(write=False)
        object.__setattr__(self, "image", a)


@dataclass(frozen=True, eq=False)
class LedObservation:
    """Where a camera found a child's LEDs (one switching sequence).

    Attributes:
        camera, child: names. timestamp: time of the sequence's last frame, s.
        pixels: (N_led, 2) image positions, px; NaN rows for LEDs not found.
        sigma_px: (N_led,) predicted standard deviation of each coordinate, px (NaN if
            not found).
        failures: per LED, None when found, else the failure's name (e.g. ``"occluded"``,
            ``"not_in_view"``, ``"too_faint"``, see :class:`calib.detection.DetectionFailure`).
        frames: number of images the sequence took (0 when no image was taken).
    """

    camera: str
    child: str
    timestamp: float
    pixels: NDArray[np.float64]
    sigma_px: NDArray[np.float64]
    failures: tuple[str | None, ...]
    frames: int = 0

    def __post_init__(self) -> None:
        p = _frozen_array(self.pixels, None, "pixels")
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"pixels must be (N_led, 2), got {p.shape}")
        s = _frozen_array(self.sigma_px, (len(p),), "sigma_px")
        if len(self.failures) != len(p):
            raise ValueError(f"give one failure entry per LED ({len(p)}), got {self.failures}")
        for k, f in enumerate(self.failures):
            if (f is None) != bool(np.all(np.isfinite(p[k]))):
                raise ValueError(f"LED {k}: a pixel without failure, or a failure with a pixel")
        object.__setattr__(self, "pixels", p)
        object.__setattr__(self, "sigma_px", s)
        object.__setattr__(self, "failures", tuple(self.failures))

    @property
    def found(self) -> NDArray[np.bool_]:
        """(N_led,) which LEDs were found."""
        return np.array([f is None for f in self.failures])

    @property
    def complete(self) -> bool:
        """Whether every LED was found."""
        return bool(self.found.all())


@dataclass(frozen=True)
class Event:
    """Something that happened that is not a measurement: a lost lock, a skipped point, a
    stage starting. ``kind`` is a short snake_case name; ``details`` plain values."""

    timestamp: float
    kind: str
    message: str = ""
    details: Mapping[str, Any] = field(default_factory=dict)
