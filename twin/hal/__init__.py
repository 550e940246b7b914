"""The hardware-abstraction interface: what the campaign talks to.

- :mod:`.readings`: frozen, timestamped records (SI units) of everything a device reports.
- :mod:`.devices`: the abstract devices: :class:`Clock`, :class:`TotalStation`,
  :class:`MobileBase`, :class:`MarkerLeds`, :class:`Camera`, :class:`LedSensor`, and the
  only errors each may raise (:data:`DOCUMENTED_ERRORS`).
- :mod:`.errors`: a device that is gone (:class:`DeviceLostError`), a camera without a
  frame (:class:`NoFrameError`).
- :mod:`.led_sensing`: :class:`ImageLedSensor`, an LED sensor made of a camera and LEDs.
- :mod:`.rig`: :class:`Rig`, the devices of one campaign.
- :mod:`.wrappers`: devices that pass every call to another (:func:`wrapped`), to change
  what one device does: record it, inject a fault.
- :mod:`.recording`: :func:`recorded`, a rig whose every reading goes to a recorder.
- :mod:`.structure`: :func:`check_rig_structure`, whether a rig has what the campaign
  needs, without calling a device.
- :mod:`.conformance`: :func:`check_rig`, whether a rig keeps the interface's promises
  (every backend's tests run it).

No backend is imported here: the MuJoCo twin (:mod:`twin.sim.rig`) implements these
classes, and real drivers will.
"""

from twin.hal.conformance import check_rig
from twin.hal.devices import (
    DOCUMENTED_ERRORS,
    Camera,
    Clock,
    LedSensor,
    MarkerLeds,
    MobileBase,
    TotalStation,
)
from twin.hal.errors import DeviceLostError, NoFrameError
from twin.hal.led_sensing import ImageLedSensor
from twin.hal.readings import (
    CameraImage,
    DriveResult,
    DriveStatus,
    Event,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.hal.recording import Recorder, recorded
from twin.hal.rig import Rig
from twin.hal.structure import RigCheckError, check_rig_structure
from twin.hal.wrappers import wrapped

__all__ = [
    "DOCUMENTED_ERRORS",
    "Camera",
    "CameraImage",
    "Clock",
    "DeviceLostError",
    "DriveResult",
    "DriveStatus",
    "Event",
    "ImageLedSensor",
    "LedObservation",
    "LedSensor",
    "LedSwitch",
    "MarkerLeds",
    "MobileBase",
    "NoFrameError",
    "OdometryReading",
    "Recorder",
    "Rig",
    "RigCheckError",
    "TiltReading",
    "TotalStation",
    "TotalStationMeasurement",
    "check_rig",
    "check_rig_structure",
    "recorded",
    "wrapped",
]
