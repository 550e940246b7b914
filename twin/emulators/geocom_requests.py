"""GeoCOM's ASCII lines as the emulated instrument reads and writes them: requests
parsed, replies formatted, and the return codes it answers.

Requests are lines ``%R1Q,<RPC>[,<TrId>[,<CRC>]]:<P0>,<P1>,...``; replies are
``%R1P,<RC_COM>,<TrId>[,<CRC>]:<RC>[,<values>]`` CR LF, as in Leica's "TPS1200+/TS30/TM30
GeoCOM Reference Manual" (version 1.50). The CRC is geocompy's CRC-16.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from geocompy.communication import crc16_bytewise

OK = 0
IVPARAM = 2
FATAL = 4
TIME_OUT = 6
SYSBUSY = 13
INSTRUMENT_TILT = 22
EDM_DISTRANGE_ERR = 818
TMC_DIST_ERROR = 1292
COM_CANT_DECODE_REQ = 3080
COM_PROC_UNAVAIL = 3081
COM_SRVR_RX_CHECKSUM_ERROR = 3101
AUT_NO_TARGET = 8710

_REQUEST = re.compile(r"^%R1Q,(\d{1,9})(?:,(\d{1,9}))?(?:,(\d{1,9}))?:(.*)$")
_PARAM = re.compile(r'"[^"]*"|[^,]*')


class RequestError(ValueError):
    """A line that is not a GeoCOM request. ``trid`` is its transaction id where one could
    be read (the reply carries it), else 0."""

    def __init__(self, message: str, trid: int = 0) -> None:
        super().__init__(message)
        self.trid = trid


@dataclass(frozen=True)
class Request:
    """One parsed GeoCOM request.

    Attributes:
        rpc: the remote procedure's number.
        trid: the transaction id (0 when the request has none).
        crc: the CRC-16 the request carries, or None.
        params: the parameters as sent (strings keep their quotes).
        checksum_ok: whether the CRC (if any) matches the request.
    """

    rpc: int
    trid: int
    crc: int | None
    params: tuple[str, ...]
    checksum_ok: bool = True


def split_params(text: str) -> tuple[str, ...]:
    """Split a parameter list at the commas outside double-quoted strings."""
    if text == "":
        return ()
    params = []
    pos = 0
    while True:
        m = _PARAM.match(text, pos)
        assert m is not None  # the pattern matches the empty string
        params.append(m.group())
        pos = m.end()
        if pos >= len(text):
            return tuple(params)
        if text[pos] != ",":
            raise ValueError(f"a parameter list must separate values by commas, got {text!r}")
        pos += 1
        if pos == len(text):
            params.append("")
            return tuple(params)


def parse_request(line: bytes) -> Request:
    """Parse one request line (without its CR LF).

    Raises:
        RequestError: the line is not ASCII or not ``%R1Q,<RPC>[,<TrId>[,<CRC>]]:<params>``.
    """
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError as exc:
        raise RequestError(f"a request must be ASCII text, got {line[:40]!r}") from exc
    m = _REQUEST.match(text)
    if m is None:
        raise RequestError(f"expected %R1Q,<RPC>[,<TrId>]:<params>, got {text[:40]!r}")
    trid = int(m[2]) if m[2] is not None else 0
    try:
        params = split_params(m[4])
    except ValueError as exc:
        raise RequestError(str(exc), trid) from exc
    crc = int(m[3]) if m[3] is not None else None
    ok = True
    if crc is not None:
        ok = crc == crc16_bytewise(f"%R1Q,{m[1]},{m[2]}:{m[4]}")
    return Request(rpc=int(m[1]), trid=trid, crc=crc, params=params, checksum_ok=ok)


def format_reply(
    trid: int, rc: int, values: Sequence[str] = (), *, com: int = OK, checksum: bool = False
) -> bytes:
    """One reply line: ``%R1P,<com>,<trid>[,<crc>]:<rc>[,<values>]`` CR LF."""
    body = ",".join([str(rc), *values])
    if checksum:
        crc = crc16_bytewise(f"%R1P,{com},{trid}:{body}")
        return f"%R1P,{com},{trid},{crc}:{body}\r\n".encode("ascii")
    return f"%R1P,{com},{trid}:{body}\r\n".encode("ascii")
