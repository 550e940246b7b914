"""Pioneer 3 robots over ARCOS: the protocol (:mod:`.protocol`), one client session
(:mod:`.connection`), the base (:mod:`.base`) and a child's LEDs on the digital outputs
(:mod:`.leds`)."""

from twin.drivers.arcos.base import ArcosBase
from twin.drivers.arcos.connection import ArcosPose, PioneerConnection
from twin.drivers.arcos.leds import ArcosLeds
from twin.drivers.arcos.protocol import PLATFORMS, Command, PlatformParams, Sip

__all__ = [
    "PLATFORMS",
    "ArcosBase",
    "ArcosLeds",
    "ArcosPose",
    "Command",
    "PioneerConnection",
    "PlatformParams",
    "Sip",
]
