"""One client session with a Pioneer's ARCOS server over a serial port or a TCP bridge.

The connection opens the port (pyserial's ``serial_for_url``: a device path or
``socket://host:port``), synchronises (SYNC0, SYNC1, SYNC2: the robot answers the last with
its name, type and subtype), opens the servers (OPEN) and enables the motors (ENABLE 1).
A reader thread then decodes the SIPs the robot sends and keeps the newest, and a keep-alive
thread sends PULSE well within the robot's watchdog period. :meth:`close` stops the robot,
sends CLOSE and closes the port.

The serial line is pyserial's default 8 data bits, no parity, 1 stop bit, at 9600 baud
unless told otherwise (the rate ARCOS' HOST port and ARIA start at; HOSTBAUD, command 50,
can switch the robot to 19200-115200, which this driver does not do).

The keep-alive keeps the robot's watchdog fed for as long as the process lives, so whoever
drives must stop the robot when its own control loop fails (see
:meth:`twin.drivers.arcos.base.ArcosBase.drive_to`).

Times are rig seconds of the :class:`~twin.drivers.clock.WallClock` (converted with
:meth:`~twin.drivers.clock.WallClock.wall` wherever the connection waits).
"""

from __future__ import annotations

import contextlib
import math
import select
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import serial
from numpy.typing import NDArray

from twin.closing import Closing
from twin.drivers.arcos.platforms import PlatformParams, platform
from twin.drivers.arcos.protocol import (
    SYNC0,
    SYNC1,
    SYNC2,
    Command,
    PacketReader,
    parse_sync2_reply,
)
from twin.drivers.arcos.protocol import command as command_packet
from twin.drivers.arcos.sip import Sip, decode_sip, is_sip, unroll_position
from twin.drivers.clock import WallClock
from twin.hal.errors import DeviceLostError

WATCHDOG_S = 2.0
"""ARCOS' default watchdog: with no packet from the client for this long (s) it stops."""

PULSE_PERIOD = 0.5
"""Rig seconds between keep-alive PULSEs: a quarter of the watchdog."""

_SYNCS = (SYNC0, SYNC1, SYNC2)

POLL = 0.05
"""Rig seconds the reader waits for bytes before it looks whether it should stop."""


@dataclass(frozen=True)
class ArcosPose:
    """The robot's wheel odometry in its own frame (zero where the session opened).

    Attributes:
        timestamp: arrival of the SIP it comes from, rig clock, s.
        x, y: m (XPOS, YPOS unrolled across their 15-bit roll-over).
        yaw: rad in (-pi, pi].
        raw: (xpos, ypos, thpos) as the SIP carried them, for exact comparisons.
    """

    timestamp: float
    x: float
    y: float
    yaw: float
    raw: tuple[int, int, int]

    @property
    def pose(self) -> NDArray[np.float64]:
        """(3,) (x m, y m, yaw rad)."""
        return np.array([self.x, self.y, self.yaw])


class PioneerConnection(Closing):
    """An open ARCOS session with one robot.

    Args:
        port: what pyserial opens (``/dev/ttyUSB0``, a pty's path, ``socket://host:port``).
        model: ``p3dx`` or ``p3at`` (the robot must report the ARCOS subtype ``p3dx-sh``
            or ``p3at-sh``).
        clock: the rig's wall clock.
        baud: the serial line's speed (ignored over TCP).
        timeout_s: rig seconds without an answer (a SYNC echo, a SIP) after which the robot
            is taken for lost.
        name: the robot's name in errors and readings.
        pulse_s: rig seconds between keep-alive PULSEs (under half the watchdog, 2 s).

    Raises:
        DeviceLostError: the port would not open, or the robot did not synchronise.
        ValueError: the robot reports a subtype of another model; a bad ``timeout_s`` or
            ``pulse_s``.
    """

    def __init__(
        self,
        port: str,
        *,
        model: str,
        clock: WallClock,
        baud: int = 9600,
        timeout_s: float = 2.0,
        name: str = "robot",
        pulse_s: float = PULSE_PERIOD,
    ) -> None:
        self.params: PlatformParams = platform(model)
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s}")
        if not (math.isfinite(pulse_s) and 0 < pulse_s <= 0.5 * WATCHDOG_S):
            raise ValueError(
                f"pulse_s must be in (0, {0.5 * WATCHDOG_S}] s (the watchdog waits "
                f"{WATCHDOG_S} s), got {pulse_s}"
            )
        self.port = port
        self.link = f"{port} (ARCOS)"
        """Where and how the robot is reached, for messages: ``PORT (ARCOS)``."""
        self.clock = clock
        self.timeout_s = float(timeout_s)
        self.name = name
        self.pulse_s = float(pulse_s)
        self._reader = PacketReader()
        self.malformed = 0
        """SIPs that framed correctly but did not decode."""
        self._write_lock = threading.Lock()
        self._cond = threading.Condition()
        self._latest: Sip | None = None
        self._count = 0  # SIPs received
        self._unrolled: tuple[int, int] | None = None  # continuous xpos, ypos
        self._pose: ArcosPose | None = None
        self._lost: str | None = None
        self._closed = False
        self._stop = threading.Event()
        self.robot_name = self.robot_type = self.robot_subtype = ""
        try:
            self._serial = serial.serial_for_url(port, baudrate=baud, timeout=0)
        except (serial.SerialException, OSError, ValueError) as e:
            raise DeviceLostError(
                name, f"cannot open the port: {e}", link=self.link, port=port
            ) from None
        try:
            self._handshake()
            subtype = self.robot_subtype.lower()
            if subtype == self.params.model:
                raise ValueError(
                    f"{name}: the robot on {port} reports subtype {self.robot_subtype!r}: the "
                    "older H8 controller, whose distance units (0.485 or 0.465 mm) this driver "
                    f"does not use; expected ARCOS ({self.params.subtype!r})"
                )
            if subtype != self.params.subtype:
                raise ValueError(
                    f"{name}: the robot on {port} reports subtype {self.robot_subtype!r}, "
                    f"expected {self.params.subtype!r} (the rig file's model "
                    f"{self.params.model!r})"
                )
            self._write(command_packet(Command.OPEN))
        except (serial.SerialException, OSError) as e:
            self._abandon()
            raise self._lost_link(e) from None
        except BaseException:
            self._abandon()
            raise
        self._threads = [
            threading.Thread(target=self._read_loop, name=f"arcos-read-{name}", daemon=True),
            threading.Thread(target=self._pulse_loop, name=f"arcos-pulse-{name}", daemon=True),
        ]
        for t in self._threads:
            t.start()
        try:
            self.wait_for(lambda s: True)
            self.send(Command.ENABLE, 1)
            # Drives read the motors flag: wait until a SIP shows the motors enabled (a
            # robot whose STOP button is pressed may not enable them; that is no failure).
            with contextlib.suppress(DeviceLostError):
                self.wait_for(lambda s: s.motors_enabled or s.estop)
            self.latest()  # but a robot that fell silent meanwhile is lost
        except BaseException:
            self.close()
            raise

    def _abandon(self) -> None:
        """Close the port of a session that never opened."""
        self._closed = True
        with contextlib.suppress(Exception):
            self._serial.close()

    # -- bytes -------------------------------------------------------------------------------------
    def _read_bytes(self, wall_timeout: float) -> bytes:
        """What the port has, waiting at most ``wall_timeout`` wall seconds for the first byte."""
        ready, _, _ = select.select([self._serial.fileno()], [], [], max(wall_timeout, 0.0))
        if not ready:
            return b""
        return bytes(self._serial.read(4096))

    def _write(self, data: bytes) -> None:
        with self._write_lock:
            self._serial.write(data)

    def _handshake(self) -> None:
        """SYNC0, SYNC1, SYNC2 (each echoed) and the robot's identity."""
        deadline = self.clock.now() + self.timeout_s
        step = 0
        resend = 0.0
        while step < 3:
            now = self.clock.now()
            if now > deadline:
                raise DeviceLostError(
                    self.name,
                    f"no ARCOS robot synchronised in {self.timeout_s} s",
                    link=self.link,
                    port=self.port,
                    step=step,
                )
            if now >= resend:
                self._write(command_packet(_SYNCS[step]))
                resend = now + 0.25 * self.timeout_s
            try:
                data = self._read_bytes(self.clock.wall(POLL))
            except (serial.SerialException, OSError) as e:
                raise self._lost_link(e) from None
            for payload in self._reader.feed(data):
                if is_sip(payload):
                    # A session from an earlier client is still open: close it, start over.
                    self._write(command_packet(Command.CLOSE))
                    step, resend = 0, 0.0
                    break
                if payload[0] != _SYNCS[step]:
                    continue
                if step == SYNC2:
                    self.robot_name, self.robot_type, self.robot_subtype = parse_sync2_reply(
                        payload
                    )
                step += 1
                resend = 0.0
                if step == 3:
                    break

    # -- threads -----------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._stop.is_set():
            try:
                data = self._read_bytes(self.clock.wall(POLL))
            except (serial.SerialException, OSError, ValueError, TypeError) as e:
                if not self._stop.is_set():
                    self._mark_lost(f"connection lost: the link failed: {e}")
                return
            if not data:
                continue
            now = self.clock.now()
            for payload in self._reader.feed(data):
                if not is_sip(payload):
                    continue
                try:
                    sip = decode_sip(payload, now)
                except ValueError:
                    self.malformed += 1
                    continue
                self._take(sip)

    def _take(self, sip: Sip) -> None:
        previous = (None, None) if self._unrolled is None else self._unrolled
        ux = unroll_position(previous[0], sip.xpos)
        uy = unroll_position(previous[1], sip.ypos)
        self._unrolled = (ux, uy)
        p = self.params
        pose = ArcosPose(
            sip.timestamp,
            p.position_m(ux),
            p.position_m(uy),
            p.heading_rad(sip.thpos),
            (sip.xpos, sip.ypos, sip.thpos),
        )
        with self._cond:
            self._latest = sip
            self._pose = pose
            self._count += 1
            self._cond.notify_all()

    def _pulse_loop(self) -> None:
        while not self._stop.wait(self.clock.wall(self.pulse_s)):
            try:
                self._write(command_packet(Command.PULSE))
            except (serial.SerialException, OSError, ValueError, TypeError) as e:
                if not self._stop.is_set():
                    self._mark_lost(f"connection lost: the link failed: {e}")
                return

    def _mark_lost(self, why: str) -> None:
        with self._cond:
            if self._lost is None:
                self._lost = why
            self._cond.notify_all()

    # -- the public side ---------------------------------------------------------------------
    @property
    def rejected(self) -> dict[str, int]:
        """What the reader threw away: garbage bytes, packets with a bad checksum or cut
        short, SIPs that did not decode."""
        return {**self._reader.rejected, "malformed": self.malformed}

    @property
    def sip_count(self) -> int:
        """Number of SIPs received so far."""
        return self._count

    def _check(self) -> None:
        if self._lost is not None:
            raise DeviceLostError(self.name, self._lost, link=self.link, port=self.port)
        if self._closed:
            raise DeviceLostError(
                self.name, "the connection is closed", link=self.link, port=self.port
            )

    def _lost_link(self, error: BaseException) -> DeviceLostError:
        """The error of a link that failed under a read or a write (``error``)."""
        return DeviceLostError(
            self.name, f"connection lost: the link failed: {error}", link=self.link, port=self.port
        )

    def identify(self) -> dict[str, object]:
        """The robot's name, type and subtype (its SYNC2 answer) and battery voltage, V."""
        return {
            "name": self.robot_name,
            "type": self.robot_type,
            "subtype": self.robot_subtype,
            "battery_v": self.latest().battery_volts,
        }

    def latest(self) -> Sip:
        """The newest SIP (its ``timestamp`` is its arrival on the rig clock).

        Raises:
            DeviceLostError: the link failed, or no SIP came for ``timeout_s``.
        """
        with self._cond:
            sip = self._latest
        return self._fresh(sip)

    def _fresh(self, sip: Sip | None) -> Sip:
        """``sip``, checked to be recent and the link to be up."""
        with self._cond:
            self._check()
        if sip is None or self.clock.now() - sip.timestamp > self.timeout_s:
            age = "ever" if sip is None else f"{self.clock.now() - sip.timestamp:.2f} s"
            raise DeviceLostError(
                self.name,
                f"connection lost: no SIP from the robot for {age}",
                link=self.link,
                port=self.port,
            )
        return sip

    def pose(self) -> ArcosPose:
        """The odometry of the newest SIP (raises as :meth:`latest`)."""
        with self._cond:
            sip, pose = self._latest, self._pose
        self._fresh(sip)
        assert pose is not None
        return pose

    def wait_for(
        self, predicate: Callable[[Sip], bool], timeout_s: float | None = None, after: int = -1
    ) -> Sip:
        """Wait for a SIP that satisfies ``predicate``: the next one to arrive (or one
        already received beyond number ``after``, see :attr:`sip_count`).

        Args:
            predicate: tests a SIP.
            timeout_s: rig seconds to wait (default ``timeout_s``).
            after: accept only SIPs numbered above this (default: the next one).

        Raises:
            DeviceLostError: the link failed, or no such SIP came in time (with no SIP at
                all for ``timeout_s`` the robot is lost; with SIPs that never satisfy the
                predicate, too: it did not do what it was told).
        """
        limit = self.timeout_s if timeout_s is None else float(timeout_s)
        deadline = self.clock.now() + limit
        with self._cond:
            seen = self._count if after < 0 else after
            while True:
                self._check()
                if self._count > seen:
                    seen = self._count
                    sip = self._latest
                    assert sip is not None
                    if predicate(sip):
                        return sip
                left = deadline - self.clock.now()
                if left <= 0:
                    raise DeviceLostError(
                        self.name,
                        f"no SIP as expected from the robot in {limit} s",
                        link=self.link,
                        port=self.port,
                        sips=self._count,
                    )
                self._cond.wait(self.clock.wall(min(left, POLL)))

    def send(self, number: int, argument: Any = None) -> None:
        """Send one command (its number and argument, see
        :func:`twin.drivers.arcos.protocol.command`).

        Raises:
            DeviceLostError: the link failed or is closed.
        """
        packet = command_packet(number, argument)
        with self._cond:
            self._check()
        try:
            self._write(packet)
        except (serial.SerialException, OSError, ValueError, TypeError) as e:
            self._mark_lost(f"connection lost: the link failed: {e}")
            raise self._lost_link(e) from None

    def write_raw(self, data: bytes) -> None:
        """Put bytes on the line as they are (a diagnostic: what a noisy line does)."""
        self._write(bytes(data))

    @property
    def lost(self) -> bool:
        """Whether the link failed."""
        return self._lost is not None

    def close(self) -> None:
        """Stop the robot (VEL 0, RVEL 0), CLOSE, close the port. Twice is harmless."""
        if self._closed:
            return
        self._closed = True
        if self._lost is None:
            with contextlib.suppress(Exception):
                for number, arg in ((Command.VEL, 0), (Command.RVEL, 0), (Command.CLOSE, None)):
                    self._write(command_packet(number, arg))
        self._stop.set()
        for t in getattr(self, "_threads", []):
            if t is not threading.current_thread():
                t.join(timeout=2.0)
        with contextlib.suppress(Exception):
            self._serial.close()
        with self._cond:
            self._cond.notify_all()
