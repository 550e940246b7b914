"""The devices the campaign talks to: small abstract classes, sensors and actuators.

A backend (the MuJoCo twin at either fidelity, or real hardware) implements them; the
campaign is written against these classes only. Everything that holds a device is
:class:`twin.closing.Closing`: it has ``close()`` and works as a context manager.

Frames: the total station measures in its levelled frame (x along the instrument's
horizontal zero direction, z up; :mod:`twin.instruments.tilt`). Bases drive in the world
frame W as far as their own localisation knows it; :meth:`MobileBase.set_pose` corrects that
localisation from an external fix (CPS).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from types import MappingProxyType

from numpy.typing import ArrayLike

from calib.detection.sequence import SwitchingSequence
from twin.closing import Closing
from twin.hal.errors import DeviceLostError, NoFrameError
from twin.hal.readings import (
    CameraImage,
    DriveResult,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.instruments.errors import (
    DistanceMeasurementError,
    InstrumentBusyError,
    InstrumentFaultError,
    InstrumentTimeoutError,
    LineOfSightBlockedError,
    NoPrismInConeError,
    OutOfRangeError,
    TiltOutOfRangeError,
)
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec

_INSTRUMENT_LINK = (
    InstrumentBusyError,
    InstrumentTimeoutError,
    InstrumentFaultError,
    DeviceLostError,
)
"""What any request to a real instrument may end with: it is busy, it did not answer in
time, it answered an error code of its own, it is gone."""

DOCUMENTED_ERRORS: Mapping[str, tuple[type[Exception], ...]] = MappingProxyType(
    {
        "Clock.now": (),
        "Clock.sleep": (ValueError,),
        "TotalStation.point": (ValueError, *_INSTRUMENT_LINK),
        "TotalStation.measure": (
            NoPrismInConeError,
            LineOfSightBlockedError,
            OutOfRangeError,
            TiltOutOfRangeError,
            DistanceMeasurementError,
            *_INSTRUMENT_LINK,
        ),
        "TotalStation.read_inclination": (TiltOutOfRangeError, *_INSTRUMENT_LINK),
        "MobileBase.drive_to": (DeviceLostError,),
        "MobileBase.odometry": (DeviceLostError,),
        "MobileBase.set_pose": (ValueError, DeviceLostError),
        "MarkerLeds.switch": (ValueError, DeviceLostError),
        "Camera.capture": (NoFrameError, DeviceLostError),
        "LedSensor.observe": (ValueError, DeviceLostError),
    }
)
"""The only errors each device method may raise (:func:`twin.hal.conformance.check_rig`
holds a device to them). Everything else a device reports is a reading: a drive that
fails ends with a :class:`DriveStatus`, an LED that is not found has a failure in its
:class:`LedObservation`. ``ValueError`` stands for a bad argument: a negative time, an aim
that is not a finite non-zero (3,) point, a non-finite pose, not one flag per LED, a child
the sensor has no LEDs of. :class:`twin.hal.errors.DeviceLostError` is a device whose
link is gone (a real device only); the instrument's link errors (busy, timeout, an error
code of its own) are in :mod:`twin.instruments.errors`."""


class Clock(Closing):
    """The rig's time base."""

    @abstractmethod
    def now(self) -> float:
        """Seconds since the rig started."""

    @abstractmethod
    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass (a simulation advances its world).

        Raises:
            ValueError: ``seconds`` is negative.
        """

    def close(self) -> None:
        """A clock holds nothing."""


class TotalStation(Closing):
    """A total station with automatic aim and a two-axis inclination sensor.

    Raises from :meth:`measure`: :class:`twin.instruments.errors.NoPrismInConeError` (the
    automatic aim found no prism: a lost lock), ``LineOfSightBlockedError``,
    ``OutOfRangeError``, ``TiltOutOfRangeError``, ``DistanceMeasurementError``; from every
    method of a real instrument also ``InstrumentBusyError``, ``InstrumentTimeoutError``,
    ``InstrumentFaultError`` and :class:`twin.hal.errors.DeviceLostError`.
    """

    @property
    @abstractmethod
    def spec(self) -> TotalStationSpec:
        """The instrument's noise, resolution, range and aim cone."""

    @property
    @abstractmethod
    def inclinometer(self) -> InclinometerSpec | None:
        """The inclination sensor's specification; None if the shots are not levelled."""

    @abstractmethod
    def point(self, target_level: ArrayLike) -> None:
        """Turn the telescope towards a predicted prism position, (3,) m, levelled frame.

        Raises:
            ValueError: the target is not a finite non-zero (3,) point.
        """

    @abstractmethod
    def measure(self) -> TotalStationMeasurement:
        """Lock onto the prism nearest the pointing direction and measure it (levelled)."""

    @abstractmethod
    def read_inclination(self) -> TiltReading:
        """One reading of the inclination sensor.

        Raises:
            TiltOutOfRangeError: the instrument leans beyond the sensor's working range.
        """


class MobileBase(Closing):
    """A wheeled robot base that drives to goals by its own localisation."""

    @property
    @abstractmethod
    def name(self) -> str:
        """The robot's name."""

    @abstractmethod
    def drive_to(self, goal_xy: ArrayLike, goal_yaw: float | None = None) -> DriveResult:
        """Drive to (x, y) m, turn to ``goal_yaw`` rad if given, stop; block until stopped."""

    @abstractmethod
    def odometry(self) -> OdometryReading:
        """The base's current pose estimate."""

    @abstractmethod
    def set_pose(self, x: float, y: float, yaw: float) -> None:
        """Correct the base's pose estimate from an external fix (m, rad).

        Raises:
            ValueError: the pose is not finite.
        """


class MarkerLeds(Closing):
    """The LEDs of a child's marker assembly."""

    @property
    @abstractmethod
    def child(self) -> str:
        """The child's name."""

    @property
    @abstractmethod
    def count(self) -> int:
        """Number of LEDs."""

    @abstractmethod
    def switch(self, on: Sequence[bool]) -> LedSwitch:
        """Light the LEDs whose flag is True and switch off the others.

        Raises:
            ValueError: not one flag per LED.
        """


class Camera(Closing):
    """A fixed camera."""

    @property
    @abstractmethod
    def name(self) -> str:
        """The camera's name."""

    @property
    @abstractmethod
    def image_size(self) -> tuple[int, int]:
        """(width, height), px."""

    @abstractmethod
    def capture(self) -> CameraImage:
        """Take one image now (one begun after the call).

        Raises:
            twin.hal.errors.NoFrameError: no image came in the time allowed.
        """


class LedSensor(Closing):
    """A camera's view of the children's LEDs: where it finds each LED of a child.

    With images this is a camera, the child's LEDs and on/off subtraction
    (:class:`twin.hal.led_sensing.ImageLedSensor`); a backend may implement it directly.
    """

    @property
    @abstractmethod
    def camera(self) -> str:
        """The camera's name."""

    @property
    @abstractmethod
    def image_size(self) -> tuple[int, int]:
        """(width, height), px."""

    @abstractmethod
    def observe(self, child: str, sequence: SwitchingSequence) -> LedObservation:
        """Run ``sequence`` on the child's LEDs and find each LED in the camera's image.

        Raises:
            ValueError: the sensor has no LEDs of ``child``.
        """

    def last_image(self) -> CameraImage | None:
        """The image the last :meth:`observe` found the LEDs in (each pixel at its
        brightest over the sequence's frames, so that every LED shows lit), for the
        record; None where the sensor takes no images (or has observed nothing yet)."""
        return None
