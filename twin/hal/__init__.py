"""The hardware-abstraction interface: what the campaign talks to.

- :mod:`.readings`: frozen, timestamped records (SI units) of everything a device reports.
- :mod:`.devices`: the abstract devices: :class:`Clock`, :class:`TotalStation`,
  :class:`MobileBase`, :class:`MarkerLeds`, :class:`Camera`, :class:`LedSensor`.
- :mod:`.led_sensing`: :class:`ImageLedSensor`, an LED sensor made of a camera and LEDs.
- :mod:`.rig`: :class:`Rig`, the devices of one campaign.
- :mod:`.recording`: :func:`recorded`, a rig whose every reading goes to a recorder.

No backend is imported here: the MuJoCo twin (:mod:`twin.sim.rig`) implements these
classes, and real drivers will.
"""

from twin.hal.devices import Camera, Clock, LedSensor, MarkerLeds, MobileBase, TotalStation
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

__all__ = [
    "Camera",
    "CameraImage",
    "Clock",
    "DriveResult",
    "DriveStatus",
    "Event",
    "ImageLedSensor",
    "LedObservation",
    "LedSensor",
    "LedSwitch",
    "MarkerLeds",
    "MobileBase",
    "OdometryReading",
    "Recorder",
    "Rig",
    "TiltReading",
    "TotalStation",
    "TotalStationMeasurement",
    "recorded",
]
