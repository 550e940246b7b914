"""The server information packet (SIP) of the ARCOS protocol: what a Pioneer 3 robot
reports several times a second, decoded, encoded, and its positions unrolled.

Written from the Pioneer 3 Operations Manual (chapter "ARCOS": server information packets).
A standard SIP is a packet (:mod:`.protocol`) whose payload starts with a type byte ``0x3S``
(S = 2: motors stopped, 3: robot moving), followed by the fields of :class:`Sip`, in the
protocol's units (:mod:`.platforms` turns them into SI).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from twin.drivers.arcos.protocol import ProtocolError, frame

SIP_STOPPED = 0x32
SIP_MOVING = 0x33

STALL_LEFT = 1 << 0
"""STALL AND BUMPERS bit: the left wheel stalled (bits 1-7 the first bumper)."""
STALL_RIGHT = 1 << 8
"""STALL AND BUMPERS bit: the right wheel stalled (bits 9-15 the second bumper)."""

FLAG_MOTORS = 1 << 0
"""FLAGS bit 0: the motors are enabled."""
FLAG_ESTOP = 1 << 5
"""FLAGS bit 5: the STOP (emergency stop) button is pressed or not yet relieved."""
FLAG_ESTALL = 1 << 6
"""FLAGS bit 6: E_STALL engaged (a stop that also disabled the motors)."""


@dataclass(frozen=True)
class Sip:
    """One standard server information packet, in the protocol's units.

    Attributes:
        timestamp: when it arrived, rig clock, s (0 for one not received).
        moving: the type byte said 0x33 (robot moving) rather than 0x32.
        xpos, ypos: wheel-encoder integrated position, 15 least significant bits,
            platform units (x DistConvFactor = mm); they roll over.
        thpos: heading, platform units (x AngleConvFactor = rad), signed.
        left_vel, right_vel: wheel velocities, platform units (x VelConvFactor = mm/s).
        battery: battery charge, tenths of a volt (one byte).
        stall_bumpers: STALL AND BUMPERS (bit 0 left stall, bits 1-7 first bumper, bit 8
            right stall, bits 9-15 second bumper).
        control: setpoint of the heading servo, platform units.
        flags: FLAGS (bit 0 motors enabled, bits 1-4 sonar arrays, bit 5 STOP button,
            bit 6 E_STALL, bits 7-8 ledge IRs, bit 9 joystick button, bit 10 charger).
        compass: compass heading, 2-degree units.
        sonars: (number, range) of the new sonar readings.
        grip_state, anport, analog, digin, digout: gripper state, selected analog port,
            its reading, user digital inputs and outputs.
        battery_x10: battery voltage, tenths of a volt (newer firmware), or None.
        charge_state: charger stage, or None.
        rotvel: rotational velocity, 0.1 deg/s (counter-clockwise positive), or None.
        fault_flags: internal fault bits, or None.
    """

    timestamp: float
    moving: bool
    xpos: int
    ypos: int
    thpos: int
    left_vel: int
    right_vel: int
    battery: int
    stall_bumpers: int
    control: int
    flags: int
    compass: int = 0
    sonars: tuple[tuple[int, int], ...] = ()
    grip_state: int = 0
    anport: int = 0
    analog: int = 0
    digin: int = 0
    digout: int = 0
    battery_x10: int | None = None
    charge_state: int | None = None
    rotvel: int | None = None
    fault_flags: int | None = None
    extra: bytes = field(default=b"", repr=False)

    @property
    def stalled(self) -> bool:
        """Either wheel reports a stall."""
        return bool(self.stall_bumpers & (STALL_LEFT | STALL_RIGHT))

    @property
    def estop(self) -> bool:
        """The emergency stop is engaged."""
        return bool(self.flags & FLAG_ESTOP)

    @property
    def motors_enabled(self) -> bool:
        """The motors are enabled."""
        return bool(self.flags & FLAG_MOTORS)

    @property
    def battery_volts(self) -> float:
        """Battery voltage, V (from BATTERYX10 when sent)."""
        return (self.battery_x10 if self.battery_x10 is not None else self.battery) / 10.0


_HEAD = struct.Struct(
    "<HHhhhBHhHB"
)  # xpos ypos thpos lvel rvel battery stall control flags compass
_TAIL = struct.Struct("<BBBBB")  # grip anport analog digin digout
_EXT = struct.Struct("<HBhH")  # battery_x10 charge_state rotvel fault_flags


def is_sip(payload: bytes) -> bool:
    """Whether a payload is a standard SIP (type byte 0x32 or 0x33)."""
    return bool(payload) and payload[0] in (SIP_STOPPED, SIP_MOVING)


def decode_sip(payload: bytes, timestamp: float = 0.0) -> Sip:
    """A :class:`Sip` from a SIP's payload (the type byte and the fields).

    Raises:
        ProtocolError: not a standard SIP, or too short for its fields.
    """
    if not is_sip(payload):
        raise ProtocolError(f"not a standard SIP: type {payload[:1].hex() or 'none'}")
    try:
        head = _HEAD.unpack_from(payload, 1)
        at = 1 + _HEAD.size
        count = payload[at]
        at += 1
        sonars = tuple(struct.unpack_from("<BH", payload, at + 3 * k) for k in range(count))
        at += 3 * count
        tail = _TAIL.unpack_from(payload, at)
        at += _TAIL.size
    except (struct.error, IndexError) as e:
        raise ProtocolError(f"a SIP of {len(payload)} bytes is too short: {e}") from None
    ext: tuple[int | None, ...] = (None, None, None, None)
    if len(payload) - at >= _EXT.size:
        ext = _EXT.unpack_from(payload, at)
        at += _EXT.size
    xpos, ypos, thpos, lvel, rvel, battery, stall, control, flags, compass = head
    return Sip(
        timestamp=float(timestamp),
        moving=payload[0] == SIP_MOVING,
        xpos=xpos & 0x7FFF,
        ypos=ypos & 0x7FFF,
        thpos=thpos,
        left_vel=lvel,
        right_vel=rvel,
        battery=battery,
        stall_bumpers=stall,
        control=control,
        flags=flags,
        compass=compass,
        sonars=tuple((int(n), int(r)) for n, r in sonars),
        grip_state=tail[0],
        anport=tail[1],
        analog=tail[2],
        digin=tail[3],
        digout=tail[4],
        battery_x10=ext[0],
        charge_state=ext[1],
        rotvel=ext[2],
        fault_flags=ext[3],
        extra=bytes(payload[at:]),
    )


def encode_sip(sip: Sip) -> bytes:
    """The whole packet of a SIP (what the robot sends). The extended fields are sent when
    ``battery_x10`` is not None (the others then default to 0)."""
    payload = bytes([SIP_MOVING if sip.moving else SIP_STOPPED])
    payload += _HEAD.pack(
        sip.xpos & 0x7FFF,
        sip.ypos & 0x7FFF,
        sip.thpos,
        sip.left_vel,
        sip.right_vel,
        sip.battery & 0xFF,
        sip.stall_bumpers & 0xFFFF,
        sip.control,
        sip.flags & 0xFFFF,
        sip.compass & 0xFF,
    )
    payload += bytes([len(sip.sonars)])
    payload += b"".join(struct.pack("<BH", n, r) for n, r in sip.sonars)
    payload += _TAIL.pack(sip.grip_state, sip.anport, sip.analog, sip.digin, sip.digout)
    if sip.battery_x10 is not None:
        payload += _EXT.pack(
            sip.battery_x10,
            sip.charge_state or 0,
            sip.rotvel or 0,
            sip.fault_flags or 0,
        )
    return frame(payload + sip.extra)


def unroll_position(previous: int | None, raw: int) -> int:
    """XPOS or YPOS made continuous across its 15-bit roll-over.

    Args:
        previous: the continuous value of the SIP before (None for the first SIP).
        raw: this SIP's 15-bit value.

    Returns:
        The continuous value nearest ``previous`` that has ``raw`` as its 15 low bits
        (the robot moves far less than half the span, 16 384 units, between two SIPs).
    """
    if previous is None:
        return raw & 0x7FFF
    delta = ((raw - previous) + 0x4000) % 0x8000 - 0x4000
    return previous + delta
