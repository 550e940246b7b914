"""The ARCOS packets of the Pioneer 3 robots, as data and pure functions: framing and
checksums, client commands, the SYNC2 answer, and a byte stream cut into packets.

Written from the Pioneer 3 Operations Manual (MobileRobots / Adept MobileRobots, chapter
"ARCOS": packet protocol, client-server connection, client commands). Nothing here touches
a port. The robot's server information packets are read and written by :mod:`.sip`; the
conversion of the protocol's units into SI by :mod:`.platforms`.

Packet (both directions)::

    0xFA 0xFB | count | payload (count - 2 bytes) | checksum (2 bytes, high byte first)

``count`` is the number of bytes after it: the payload plus the two checksum bytes (at most
200; the robot ignores a command whose count exceeds 200). The checksum runs over the
payload only: successive byte pairs are added as 16-bit big-endian words (modulo 2**16); a
last odd byte is XORed into the low byte. The manual's own examples hold:
SYNC0 is ``FA FB 03 00 00 00`` and ENABLE 1 is ``FA FB 06 04 3B 01 00 05 3B``.

A client command's payload is its number (one byte), then optionally an argument type and
the argument: ``0x3B`` a positive integer, ``0x1B`` a negative integer (its absolute value
is sent), each as two bytes, low byte first; ``0x2B`` a string (a length byte, then the
characters). Units: the protocol's own (mm, mm/s, deg/s).
"""

from __future__ import annotations

import enum
from collections.abc import Iterator
from dataclasses import dataclass, field

HEADER = b"\xfa\xfb"
"""The two bytes that start every packet."""

MAX_COUNT = 200
"""The largest byte count a packet may carry (payload plus checksum)."""

MIN_COUNT = 3
"""The smallest: a command number and the checksum."""


class Command(enum.IntEnum):
    """Client command numbers (those this project uses)."""

    PULSE = 0
    """Resets the server's watchdog (SYNC0 before a session)."""
    OPEN = 1
    """Starts the servers: the robot sends SIPs."""
    CLOSE = 2
    """Closes the servers and the session."""
    POLLING = 3
    ENABLE = 4
    """1 enables the motors, 0 disables them."""
    SETA = 5
    """Translational acceleration (positive argument) or deceleration (negative), mm/s^2."""
    SETV = 6
    """Maximum translational speed, mm/s."""
    SETRV = 10
    """Maximum rotational speed, deg/s."""
    VEL = 11
    """Translational velocity, mm/s, signed."""
    RVEL = 21
    """Rotational velocity, deg/s, signed (counter-clockwise positive)."""
    STOP = 29
    """Stop (decelerating); the motors stay enabled."""
    DIGOUT = 30
    """User digital outputs: bits 8-15 are a mask selecting the outputs to change, bits 0-7
    set (1) or reset (0) the selected ones."""
    VEL2 = 32
    """Independent wheel velocities: bits 8-15 left, bits 0-7 right (signed bytes, units of
    ``Vel2Divisor`` = 20 mm/s)."""
    E_STOP = 55
    """Emergency stop: stops at once, overriding the deceleration."""


SYNC0 = 0
SYNC1 = 1
SYNC2 = 2
"""The synchronisation packets a client sends in turn before OPEN; the robot echoes SYNC0
and SYNC1 verbatim and answers SYNC2 with its name, type (class) and subtype (subclass),
three NUL-terminated strings."""


class ArgType(enum.IntEnum):
    """Argument types of a client command."""

    INT = 0x3B
    """A positive (or unsigned) integer, two bytes, low first."""
    NINT = 0x1B
    """A negative integer: its absolute value, two bytes, low first."""
    STR = 0x2B
    """A string: a length byte, then the characters."""


class ProtocolError(ValueError):
    """A packet that is not one: bad header, count, checksum or argument."""


# -- framing -----------------------------------------------------------------------------------


def checksum(payload: bytes) -> int:
    """The 16-bit checksum of a packet's payload (the bytes between count and checksum)."""
    c = 0
    n = len(payload)
    for i in range(0, n - 1, 2):
        c = (c + ((payload[i] << 8) | payload[i + 1])) & 0xFFFF
    if n % 2:
        c ^= payload[-1]
    return c


def frame(payload: bytes) -> bytes:
    """A whole packet around ``payload`` (1 to 198 bytes)."""
    if not 1 <= len(payload) <= MAX_COUNT - 2:
        raise ProtocolError(f"a payload has 1 to {MAX_COUNT - 2} bytes, got {len(payload)}")
    return HEADER + bytes([len(payload) + 2]) + payload + checksum(payload).to_bytes(2, "big")


def unframe(packet: bytes) -> bytes:
    """The payload of one whole packet, checked.

    Raises:
        ProtocolError: wrong header, a count that does not match the length, or a checksum
            that does not match the payload.
    """
    if len(packet) < 2 + 1 + MIN_COUNT or packet[:2] != HEADER:
        raise ProtocolError(f"a packet starts with FA FB and has >= 6 bytes, got {packet.hex()}")
    count = packet[2]
    if count != len(packet) - 3 or not MIN_COUNT <= count <= MAX_COUNT:
        raise ProtocolError(f"byte count {count} does not fit a packet of {len(packet)} bytes")
    payload = packet[3:-2]
    got = int.from_bytes(packet[-2:], "big")
    if got != checksum(payload):
        raise ProtocolError(f"checksum {got:#06x} does not match {checksum(payload):#06x}")
    return payload


# -- commands ----------------------------------------------------------------------------------

Argument = int | str | bytes | None


def command(number: int, argument: Argument = None) -> bytes:
    """A client command packet.

    Args:
        number: the command number, 0-255.
        argument: None (no argument), an integer in [-32767, 65535] (sent as INT, or as NINT
            when negative), or a string / bytes of at most 197 bytes (sent as STR).
    """
    if not 0 <= int(number) <= 255:
        raise ProtocolError(f"a command number is 0-255, got {number}")
    payload = bytes([int(number)])
    if argument is None:
        return frame(payload)
    if isinstance(argument, (bool, int)):
        value = int(argument)
        if not -32767 <= value <= 0xFFFF:
            raise ProtocolError(f"an integer argument is in [-32767, 65535], got {value}")
        kind = ArgType.NINT if value < 0 else ArgType.INT
        return frame(payload + bytes([kind]) + abs(value).to_bytes(2, "little"))
    text = argument.encode("latin-1") if isinstance(argument, str) else bytes(argument)
    if len(text) > MAX_COUNT - 5:
        raise ProtocolError(f"a string argument has at most {MAX_COUNT - 5} bytes")
    return frame(payload + bytes([ArgType.STR, len(text)]) + text)


def parse_command(payload: bytes) -> tuple[int, int | bytes | None]:
    """(number, argument) of a command's payload: the argument as an int (signed), bytes
    (a string) or None.

    Raises:
        ProtocolError: an unknown argument type or an argument of the wrong length.
    """
    if not payload:
        raise ProtocolError("an empty payload")
    number = payload[0]
    if len(payload) == 1:
        return number, None
    kind = payload[1]
    rest = payload[2:]
    if kind in (ArgType.INT, ArgType.NINT):
        if len(rest) != 2:
            raise ProtocolError(f"command {number}: an integer argument has 2 bytes, got {rest}")
        value = int.from_bytes(rest, "little")
        return number, -value if kind == ArgType.NINT else value
    if kind == ArgType.STR:
        if not rest or rest[0] != len(rest) - 1:
            raise ProtocolError(f"command {number}: a string argument's length byte is wrong")
        return number, bytes(rest[1:])
    raise ProtocolError(f"command {number}: unknown argument type {kind:#04x}")


# -- the SYNC2 answer ----------------------------------------------------------------------------


def sync2_reply(name: str, kind: str, subtype: str) -> bytes:
    """The robot's answer to SYNC2: the command number 2, then its name, type and subtype as
    NUL-terminated strings."""
    text = b"".join(s.encode("latin-1") + b"\0" for s in (name, kind, subtype))
    return frame(bytes([SYNC2]) + text)


def parse_sync2_reply(payload: bytes) -> tuple[str, str, str]:
    """(name, type, subtype) from the payload of the answer to SYNC2 (missing ones "")."""
    if not payload or payload[0] != SYNC2:
        raise ProtocolError(f"not an answer to SYNC2: {payload.hex()}")
    parts = payload[1:].split(b"\0")
    parts = [p.decode("latin-1") for p in parts[:3]] + [""] * 3
    return parts[0], parts[1], parts[2]


# -- the byte stream -----------------------------------------------------------------------------


@dataclass
class PacketReader:
    """Cuts a byte stream into packet payloads, as the robot and its clients do.

    Bytes before a header are skipped (counted as ``garbage``); a packet whose checksum
    does not match is dropped (``bad_checksum``, or ``truncated`` when another header
    begins inside it: the packet was cut short) and the search goes on from the byte after
    its header, so a good packet that followed is still found. Counts are bytes for
    ``garbage`` and packets for the others.
    """

    buffer: bytearray = field(default_factory=bytearray)
    garbage: int = 0
    bad_checksum: int = 0
    truncated: int = 0

    def feed(self, data: bytes) -> Iterator[bytes]:
        """Add ``data`` and yield the payload of every whole, good packet it completes."""
        self.buffer += data
        buf = self.buffer
        while True:
            start = buf.find(HEADER)
            if start < 0:
                keep = 1 if buf[-1:] == HEADER[:1] else 0
                self.garbage += len(buf) - keep
                del buf[: len(buf) - keep]
                return
            if start:
                self.garbage += start
                del buf[:start]
            if len(buf) < 3:
                return
            count = buf[2]
            if not MIN_COUNT <= count <= MAX_COUNT:
                self.garbage += 2
                del buf[:2]
                continue
            if len(buf) < 3 + count:
                return
            payload = bytes(buf[3 : 1 + count])
            got = int.from_bytes(buf[1 + count : 3 + count], "big")
            if got != checksum(payload):
                if buf.find(HEADER, 2, 3 + count) >= 0:
                    self.truncated += 1
                else:
                    self.bad_checksum += 1
                del buf[:2]
                continue
            del buf[: 3 + count]
            yield payload

    @property
    def rejected(self) -> dict[str, int]:
        """What was thrown away so far."""
        return {
            "garbage_bytes": self.garbage,
            "bad_checksum": self.bad_checksum,
            "truncated": self.truncated,
        }
