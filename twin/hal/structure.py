"""Does a rig have what the campaign needs? :func:`check_rig_structure` looks at the
devices without calling one: a total station, a parent and at least two children, each
child with its LEDs (one count for all), at least one LED sensor (one for every camera to
calibrate), names that agree with their keys, image sizes of positive pixels.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from twin.hal.devices import (
    Camera,
    Clock,
    LedSensor,
    MarkerLeds,
    MobileBase,
    TotalStation,
)
from twin.hal.rig import Rig
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


class RigCheckError(AssertionError):
    """A rig breaks a promise of the interface: the message names the device, the call
    and what was wrong."""


def check_rig_structure(rig: Rig, cameras: Iterable[str] = ()) -> None:
    """Refuse a rig that lacks what the campaign needs, without calling a device.

    Args:
        rig: the rig.
        cameras: cameras the campaign will calibrate: each needs an LED sensor.

    Raises:
        RigCheckError: naming every problem found.
    """
    problems = _structure_problems(rig, list(cameras))
    if problems:
        raise RigCheckError("the rig lacks what the campaign needs:\n- " + "\n- ".join(problems))


def _structure_problems(rig: Rig, cameras: Sequence[str]) -> list[str]:
    out: list[str] = []
    kinds = (
        ("clock", rig.clock, Clock),
        ("total_station", rig.total_station, TotalStation),
        ("parent", rig.parent, MobileBase),
    )
    for name, device, kind in kinds:
        if not isinstance(device, kind):
            out.append(f"{name} must be a twin.hal {kind.__name__}, got {type(device).__name__}")
    if out:
        return out
    if not isinstance(rig.total_station.spec, TotalStationSpec):
        out.append("total_station.spec must be a TotalStationSpec")
    tilt = rig.total_station.inclinometer
    if tilt is not None and not isinstance(tilt, InclinometerSpec):
        out.append("total_station.inclinometer must be an InclinometerSpec or None")
    if len(rig.children) < 2:
        out.append(f"CPS needs at least two children, got {sorted(rig.children)}")
    if rig.parent.name in rig.children:
        out.append(f"the parent and a child are both called {rig.parent.name!r}")
    counts = set()
    for key, base in rig.children.items():
        if not isinstance(base, MobileBase):
            out.append(f"children[{key!r}] must be a MobileBase, got {type(base).__name__}")
            continue
        if base.name != key:
            out.append(f"children[{key!r}] is called {base.name!r}")
        leds = rig.leds.get(key)
        if not isinstance(leds, MarkerLeds):
            out.append(f"child {key!r} has no MarkerLeds")
            continue
        if leds.child != key:
            out.append(f"leds[{key!r}] belong to {leds.child!r}")
        if not isinstance(leds.count, int) or leds.count < 1:
            out.append(f"leds[{key!r}].count must be a positive int, got {leds.count!r}")
        counts.add(leds.count)
    if len(counts) > 1:
        out.append(f"every child must carry as many LEDs, got counts {sorted(counts)}")
    if not rig.led_sensors:
        out.append("there is no LED sensor: no camera can be calibrated")
    views: list[tuple[str, Mapping[str, Any], type]] = [
        ("led_sensors", rig.led_sensors, LedSensor),
        ("cameras", rig.cameras, Camera),
    ]
    for label, devices, kind in views:
        for key, device in devices.items():
            where = f"{label}[{key!r}]"
            if not isinstance(device, kind):
                out.append(f"{where} must be a {kind.__name__}, got {type(device).__name__}")
                continue
            camera = device.camera if isinstance(device, LedSensor) else device.name
            if camera != key:
                out.append(f"{where} belongs to camera {camera!r}")
            out += _image_size_problems(where, device.image_size)
    missing = [c for c in cameras if c not in rig.led_sensors]
    if missing:
        out.append(
            f"no LED sensor for the cameras {missing}; the rig has {sorted(rig.led_sensors)}"
        )
    return out


def _image_size_problems(where: str, size: object) -> list[str]:
    ok = (
        isinstance(size, tuple)
        and len(size) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)
    )
    return [] if ok else [f"{where}.image_size must be (width, height) in pixels, got {size!r}"]
