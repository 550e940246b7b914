"""The twin's total station answering Leica GeoCOM (ASCII protocol) on a pty or TCP link.

Requests are lines ``%R1Q,<RPC>[,<TrId>[,<CRC>]]:<P0>,<P1>,...`` ended by CR LF (a bare LF
before a request, as clients send to clear the line, is ignored); replies are
``%R1P,<RC_COM>,<TrId>[,<CRC>]:<RC>[,<values>]`` CR LF, as in Leica's "TPS1200+/TS30/TM30
GeoCOM Reference Manual" (version 1.50); :mod:`twin.emulators.geocom_requests` reads and
writes them. The emulator answers with a wrapped :class:`twin.hal.TotalStation`, called
only while holding the shared ``lock``: the RPCs answered, and what each does, are those
of :mod:`twin.emulators.geocom_instrument`.

Any other RPC gets ``COM_PROC_UNAVAIL`` (3081) in ``RC_COM``; a line that is not a
request, ``COM_CANT_DECODE_REQ`` (3080); a wrong checksum ``COM_SRVR_RX_CHECKSUM_ERROR``
(3101); parameters that do not parse, ``IVPARAM`` (2). :class:`GeoComFaults` makes the
emulator misbehave on purpose.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable

from twin.closing import Closing
from twin.emulators.geocom_faults import GARBAGE, Fault, GeoComFaults
from twin.emulators.geocom_instrument import GeoComInstrument
from twin.emulators.geocom_requests import (
    COM_CANT_DECODE_REQ,
    FATAL,
    OK,
    RequestError,
    format_reply,
    parse_request,
)
from twin.emulators.links import Link, PtyLink
from twin.hal.devices import TotalStation

MAX_LINE = 4096
"""Bytes without a line end after which the input is dropped as garbage."""


class GeoComEmulator(Closing):
    """A GeoCOM instrument played by a :class:`twin.hal.TotalStation`.

    Args:
        station: the instrument that answers (the twin's, or any other).
        lock: held around every call of ``station`` (the world is shared).
        link: the byte link to serve on; default a new :class:`PtyLink`. The emulator
            closes it.
        instrument_name: what ``CSV_GetInstrumentName`` answers (no quotes or line ends).
        serial_number: what ``CSV_GetInstrumentNo`` answers (decimal digits).
        faults: misbehaviour a test sets at run time; default none (:attr:`faults`).

    Raises:
        ValueError: a name with quotes or line ends, a serial number that is not digits.
    """

    def __init__(
        self,
        station: TotalStation,
        lock: threading.RLock,
        *,
        link: Link | None = None,
        instrument_name: str = "TS16 R500",
        serial_number: str = "1234567",
        faults: GeoComFaults | None = None,
    ) -> None:
        self.instrument = GeoComInstrument(
            station, lock, instrument_name=instrument_name, serial_number=serial_number
        )
        """The instrument's state and its RPCs."""
        self.faults = faults if faults is not None else GeoComFaults()
        self._link = link if link is not None else PtyLink()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False
        self.requests = 0
        """Requests answered or faulted so far (a count for tests)."""

    @property
    def address(self) -> str:
        """What a driver opens: the pty's path or ``socket://127.0.0.1:PORT``."""
        return self._link.address

    @property
    def link(self) -> Link:
        """The link served on."""
        return self._link

    def start(self) -> GeoComEmulator:
        """Serve in a daemon thread; returns self."""
        if self._closed:
            raise RuntimeError("the GeoCOM emulator is closed; start a new one")
        if self._thread is not None:
            raise RuntimeError("the GeoCOM emulator is already serving")
        self._thread = threading.Thread(target=self._serve, name="geocom-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and close the link; twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._link.close()

    # -- serving ----------------------------------------------------------------------------

    def _serve(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            began = time.monotonic()
            data = self._link.read(4096, 0.05)
            if not data:
                if time.monotonic() - began < 0.01:  # a dropped link answers at once
                    self._stop.wait(0.05)
                continue
            buffer += data
            while b"\n" in buffer and not self._stop.is_set():
                line, _, buffer = buffer.partition(b"\n")
                try:
                    self.handle_line(line.rstrip(b"\r"))
                except Exception:  # the instrument reports a failure, it does not stop
                    self._link.write(format_reply(0, FATAL))
            if len(buffer) > MAX_LINE:
                buffer = b""
                self._link.write(format_reply(0, OK, com=COM_CANT_DECODE_REQ))

    def handle_line(self, line: bytes) -> None:
        """Answer one request line (without its line end) on the link; never raises for
        what the line holds."""
        if not line.strip():
            return  # a bare line end clears the line
        try:
            request = parse_request(line.strip())
        except RequestError as exc:
            self.requests += 1
            if not self._apply_fault(None, exc.trid, lambda: b""):
                self._link.write(format_reply(exc.trid, OK, com=COM_CANT_DECODE_REQ))
            return
        self.requests += 1
        if not self._apply_fault(
            request.rpc, request.trid, lambda: self.instrument.answer(request)
        ):
            self._link.write(self.instrument.answer(request))

    def _apply_fault(self, rpc: int | None, trid: int, answer: Callable[[], bytes]) -> bool:
        """Misbehave if a fault hits this request (``answer`` carries it out and gives the
        true reply); whether one did."""
        hit = self.faults.take(rpc)
        if hit is None:
            return False
        kind, code = hit
        if kind is Fault.GARBAGE:
            self._link.write(GARBAGE)
        elif kind is Fault.CODE:
            self._link.write(format_reply(trid, code))
        elif kind is Fault.WARNING:
            self._link.write(re.sub(rb":\d+", b":%d" % code, answer(), count=1))
        elif kind is Fault.TRUNCATED:
            full = answer().rstrip(b"\r\n")
            self._link.write(full[: max(1, len(full) // 2)] + b"\r\n")
        elif kind is Fault.DROP:
            self._link.drop()
        return True
