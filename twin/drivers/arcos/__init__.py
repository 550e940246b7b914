"""Pioneer 3 robots over ARCOS: the packets (:mod:`.protocol`), the robot's reports
(:mod:`.sip`), the platforms' units (:mod:`.platforms`), one client session
(:mod:`.connection`), the base (:mod:`.base`) and a child's LEDs on the digital outputs
(:mod:`.leds`)."""

from twin.drivers.arcos.base import ArcosBase
from twin.drivers.arcos.connection import ArcosPose, PioneerConnection
from twin.drivers.arcos.leds import ArcosLeds
from twin.drivers.arcos.platforms import PLATFORMS, PlatformParams
from twin.drivers.arcos.protocol import Command
from twin.drivers.arcos.sip import Sip

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
