"""The set of devices one campaign runs with, chosen in one place and handed in."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from twin.closing import Closing
from twin.hal.devices import Camera, Clock, LedSensor, MarkerLeds, MobileBase, TotalStation


@dataclass
class Rig(Closing):
    """A parent with its total station, the children with their LEDs, the fixed cameras.

    Attributes:
        clock: the time base.
        total_station: the parent's instrument.
        parent: the parent's base.
        children: each child's base, by name.
        leds: each child's LEDs, by child name.
        led_sensors: each camera's LED sensor, by camera name.
        cameras: each camera's image source, by name (empty when the backend has no images).
        timings: seconds the backend spent by activity (``render``, ``physics``...), for
            reports; a backend that does not measure leaves it empty.
    """

    clock: Clock
    total_station: TotalStation
    parent: MobileBase
    children: Mapping[str, MobileBase]
    leds: Mapping[str, MarkerLeds]
    led_sensors: Mapping[str, LedSensor]
    cameras: Mapping[str, Camera] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        missing = set(self.children) - set(self.leds)
        if missing:
            raise ValueError(f"children without LEDs: {sorted(missing)}")
        if len(self.children) < 2:
            raise ValueError(f"CPS needs at least two children, got {sorted(self.children)}")

    def base(self, name: str) -> MobileBase:
        """The parent's or a child's base by name."""
        if name == self.parent.name:
            return self.parent
        try:
            return self.children[name]
        except KeyError:
            raise ValueError(
                f"no robot {name!r}; robots are {[self.parent.name, *self.children]}"
            ) from None

    def close(self) -> None:
        """Close every device once (sensors first, the clock last)."""
        seen: set[int] = set()
        devices: list[Closing] = [
            *self.led_sensors.values(),
            *self.cameras.values(),
            *self.leds.values(),
            *self.children.values(),
            self.parent,
            self.total_station,
            self.clock,
        ]
        for d in devices:
            if id(d) not in seen:
                seen.add(id(d))
                d.close()
