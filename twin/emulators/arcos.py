"""The twin playing a Pioneer 3's ARCOS server on a pty or a localhost TCP port.

The emulator answers as the robot does: it echoes SYNC0 and SYNC1, answers SYNC2 with the
robot's name, type and subtype, and after OPEN sends a standard SIP every ``sip_period_s``.
ENABLE switches the motors, VEL and RVEL set the velocities (ignored while the motors are
disabled), E_STOP and STOP stop, DIGOUT sets the user outputs (some of which may light a
child's LEDs in the world), PULSE only resets the watchdog, CLOSE stops the robot and ends
the session. With no packet for ``watchdog_s`` the robot stops, as ARCOS does; the next
packet (a PULSE too) revives it and it accelerates again to the speeds it was last told, as
the manual says of the watchdog. A packet with a wrong checksum, one cut short and bytes
between packets are dropped, and the session goes on.

Time is the emulator's :class:`~twin.drivers.clock.WallClock` (rig seconds, with the same
``time_scale`` as the driver's).
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from twin.closing import Closing
from twin.drivers.arcos.platforms import platform
from twin.drivers.arcos.protocol import (
    SYNC0,
    SYNC1,
    SYNC2,
    Command,
    PacketReader,
    ProtocolError,
    frame,
    parse_command,
    sync2_reply,
)
from twin.drivers.arcos.sip import FLAG_ESTOP, FLAG_MOTORS, STALL_LEFT, STALL_RIGHT, Sip, encode_sip
from twin.drivers.clock import WallClock
from twin.emulators.links import Link, TcpLink
from twin.emulators.pioneer_body import PioneerBody
from twin.hal.devices import MarkerLeds

BATTERY_V = 13.0
"""The battery voltage the robot reports, V (charged 12 V lead-acid batteries)."""

COMMANDS_KEPT = 1000
"""How many of the latest commands :attr:`PioneerEmulator.commands` keeps."""

ROBOT_TYPE = "Pioneer"
"""The type the robot reports in its SYNC2 answer."""


@dataclass
class ArcosFaults:
    """Faults a test switches on while the emulator runs.

    Attributes:
        silent: send no SIPs (the robot still hears and obeys).
        drop_link: break the link once (then cleared); the session ends.
        estop: the emergency stop is pressed: the robot stops and SIPs say so.
        stall: the wheels stall: the robot does not move and SIPs say so.
        corrupt_sips: the checksum of this many next SIPs is wrong.
        truncate_sips: this many next SIPs are cut short.
        garbage: bytes sent once before the next SIP.
    """

    silent: bool = False
    drop_link: bool = False
    estop: bool = False
    stall: bool = False
    corrupt_sips: int = 0
    truncate_sips: int = 0
    garbage: bytes = b""


class PioneerEmulator(Closing):
    """An ARCOS robot: the twin's :class:`PioneerBody` on a byte link.

    Args:
        body: the robot in the world.
        model: ``p3dx`` or ``p3at`` (its conversion factors and subtype).
        time: the emulator's clock.
        link: where the driver connects (default: a new :class:`TcpLink`).
        leds: the child's LEDs that some outputs drive (None: no LEDs).
        led_bits: ``led_bits[k]`` is the digital output of LED k of ``leds``.
        watchdog_s: rig seconds without a command after which the robot stops.
        sip_period_s: rig seconds between SIPs.
        faults: the faults to play (default: none; see :attr:`faults`).
        robot_name: the name in the SYNC2 answer (default the body's).
    """

    def __init__(
        self,
        body: PioneerBody,
        *,
        model: str,
        time: WallClock,
        link: Link | None = None,
        leds: MarkerLeds | None = None,
        led_bits: Sequence[int] = (),
        watchdog_s: float = 2.0,
        sip_period_s: float = 0.1,
        faults: ArcosFaults | None = None,
        robot_name: str | None = None,
    ) -> None:
        self.params = platform(model)
        if leds is not None and len(led_bits) != leds.count:
            raise ValueError(f"give one output bit per LED ({leds.count}), got {tuple(led_bits)}")
        for label, value in (("watchdog_s", watchdog_s), ("sip_period_s", sip_period_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} must be a positive number of seconds, got {value!r}")
        self.body = body
        self.time = time
        self.link = link if link is not None else TcpLink()
        self.leds = leds
        self.led_bits = tuple(int(b) for b in led_bits)
        self.watchdog_s = float(watchdog_s)
        self.sip_period_s = float(sip_period_s)
        self.faults = faults if faults is not None else ArcosFaults()
        self.robot_name = body.name if robot_name is None else robot_name
        self.reader = PacketReader()
        self.commands: deque[tuple[int, int | bytes | None]] = deque(maxlen=COMMANDS_KEPT)
        """The latest command packets received, in order: (number, argument)."""
        self.watchdog_trips = 0
        self._sync = 0  # SYNC packets answered in order so far
        self._open = False
        self._enabled = False
        self._v = 0.0  # commanded, m/s
        self._w = 0.0  # commanded, rad/s
        self._tripped = False  # the watchdog holds the robot until the next packet
        self._digout = 0
        self._last_command = 0.0
        self._last_advance: float | None = None
        self._next_sip = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: Exception | None = None

    @property
    def address(self) -> str:
        """What the driver opens."""
        return self.link.address

    @property
    def error(self) -> Exception | None:
        """What ended the emulator's thread, if anything did (None while it runs well)."""
        return self._error

    @property
    def session_open(self) -> bool:
        """Whether a client has opened the servers."""
        return self._open

    @property
    def digout(self) -> int:
        """The user digital outputs."""
        return self._digout

    def start(self) -> PioneerEmulator:
        """Start answering (a thread)."""
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._run, name=f"arcos-emulator-{self.body.name}", daemon=True
            )
            self._thread.start()
        return self

    # -- the loop --------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                now = self.time.now()
                wait = max(0.0, min(self._next_sip - now, self.sip_period_s))
                data = self.link.read(4096, self.time.wall(wait))
                for payload in self.reader.feed(data):
                    self._handle(payload)
                now = self.time.now()
                if not data and now < self._next_sip:
                    # A link that answers at once with nothing (closed, or no driver yet).
                    self._stop.wait(self.time.wall(self._next_sip - now))
                    now = self.time.now()
                if self.faults.drop_link:
                    self.faults.drop_link = False
                    self.link.drop()
                    self._end_session()
                if now >= self._next_sip:
                    self._tick(now)
                    self._next_sip = max(self._next_sip + self.sip_period_s, now)
        except Exception as e:  # the thread ends; kept for :attr:`error`
            self._error = e

    def _tick(self, now: float) -> None:
        """Watchdog, motion, one SIP."""
        f = self.faults
        if self._open and not self._tripped and now - self._last_command > self.watchdog_s:
            if self._v or self._w:
                self.watchdog_trips += 1
            self._tripped = True
        if f.estop or f.stall:
            self._v = self._w = 0.0
            if self.body.moving:
                self.body.halt()
        dt = 0.0 if self._last_advance is None else now - self._last_advance
        self._last_advance = now
        if self._enabled and not self._tripped and not f.estop and not f.stall:
            self.body.advance(self._v, self._w, dt)
        else:
            self.body.advance(0.0, 0.0, dt)
        if self._open and not f.silent:
            self._send_sip(now)

    def _sip(self) -> Sip:
        body, p, f = self.body, self.params, self.faults
        left, right = body.wheel_speeds
        stall = STALL_LEFT | STALL_RIGHT if (body.stalled or f.stall) else 0
        flags = (FLAG_MOTORS if self._enabled else 0) | (FLAG_ESTOP if f.estop else 0)
        battery = round(BATTERY_V * 10)
        return Sip(
            timestamp=0.0,
            moving=body.moving,
            xpos=p.position_units(body.odometry[0]),
            ypos=p.position_units(body.odometry[1]),
            thpos=p.heading_units(body.odometry[2]),
            left_vel=p.wheel_units(left),
            right_vel=p.wheel_units(right),
            battery=battery,
            stall_bumpers=stall,
            control=p.heading_units(body.odometry[2]),
            flags=flags,
            digout=self._digout,
            battery_x10=battery,
            charge_state=0,
            rotvel=round(math.degrees(body.w) * 10),
            fault_flags=0,
        )

    def _send_sip(self, now: float) -> None:
        f = self.faults
        packet = encode_sip(self._sip())
        if f.garbage:
            self.link.write(f.garbage)
            f.garbage = b""
        if f.corrupt_sips > 0:
            f.corrupt_sips -= 1
            packet = packet[:-1] + bytes([packet[-1] ^ 0x5A])
        elif f.truncate_sips > 0:
            f.truncate_sips -= 1
            packet = packet[: len(packet) // 2]
        self.link.write(packet)

    # -- commands --------------------------------------------------------------------------------
    def _handle(self, payload: bytes) -> None:
        try:
            number, arg = parse_command(payload)
        except ProtocolError:
            return
        self.commands.append((number, arg))
        if not self._open:
            self._handshake(number)
            return
        self._last_command = self.time.now()
        self._tripped = False
        value = arg if isinstance(arg, int) else None
        if number == Command.PULSE:
            return
        if number == Command.CLOSE:
            self._end_session()
        elif number == Command.ENABLE:
            self._enabled = bool(value)
            if not self._enabled:
                self._v = self._w = 0.0
        elif number == Command.VEL and value is not None:
            if self._enabled:
                self._v = value / 1000.0
        elif number == Command.RVEL and value is not None:
            if self._enabled:
                self._w = math.radians(value)
        elif number == Command.VEL2 and value is not None:
            if self._enabled:
                raw = value & 0xFFFF
                left = _signed_byte(raw >> 8) * self.params.vel2_divisor / 1000.0
                right = _signed_byte(raw & 0xFF) * self.params.vel2_divisor / 1000.0
                self._v = 0.5 * (left + right)
                self._w = (right - left) / self.body.platform.track
        elif number == Command.STOP:
            self._v = self._w = 0.0
        elif number == Command.E_STOP:
            self._v = self._w = 0.0
            self.body.halt()
        elif number == Command.DIGOUT and value is not None:
            mask, bits = (value >> 8) & 0xFF, value & 0xFF
            self._set_digout((self._digout & ~mask) | (bits & mask))

    def _handshake(self, number: int) -> None:
        if number == SYNC0:
            self._sync = 1
            self.link.write(frame(bytes([SYNC0])))
        elif number == SYNC1 and self._sync == 1:
            self._sync = 2
            self.link.write(frame(bytes([SYNC1])))
        elif number == SYNC2 and self._sync == 2:
            self._sync = 3
            self.link.write(sync2_reply(self.robot_name, ROBOT_TYPE, self.params.subtype))
        elif number == Command.OPEN and self._sync == 3:
            self._open = True
            self._enabled = False
            self._v = self._w = 0.0
            self.body.reset_odometry()
            self._last_command = self.time.now()
            self._next_sip = self.time.now()
        else:
            self._sync = 0

    def _set_digout(self, value: int) -> None:
        self._digout = value & 0xFF
        if self.leds is not None:
            flags = [bool(self._digout >> b & 1) for b in self.led_bits]
            with self.body.lock:
                self.leds.switch(flags)

    def _end_session(self) -> None:
        self._open = False
        self._enabled = False
        self._tripped = False
        self._sync = 0
        self._v = self._w = 0.0

    def close(self) -> None:
        """Stop the robot and the thread, close the link. Twice is harmless."""
        self._stop.set()
        with contextlib.suppress(Exception):
            self.link.close()  # first: a thread blocked writing to a pty is let go
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._end_session()
        if self.body.moving:
            self.body.halt()


def _signed_byte(b: int) -> int:
    return b - 256 if b >= 128 else b
