"""Errors of a device's link, shared by every kind of device.

An instrument's own failures (no prism, no distance, busy) are the typed errors of
:mod:`twin.instruments.errors`; what a drive or an LED search did not do is a reading
(:class:`twin.hal.DriveStatus`, the failures of a :class:`twin.hal.LedObservation`). What
remains is a device that is gone: it stopped answering, or its serial line or socket
closed. Nothing it would measure after that can be trusted to it.
"""

from __future__ import annotations

from typing import Any


class DeviceLostError(RuntimeError):
    """A device stopped answering, or its link closed, and could not be reached again.

    The campaign records the failure and ends (what was measured before is kept). The
    message names the device and, where given, its link: ``total_station on /dev/pts/5
    (GeoCOM): connection lost (...)``.

    Attributes:
        device: the device's name (a robot, a camera, ``total_station``).
        link: where and how the device was reached, ``PORT (PROTOCOL)``; "" if not said.
        details: plain values (the port, the time waited; the link, where given).
    """

    def __init__(self, device: str, message: str, *, link: str = "", **details: Any) -> None:
        super().__init__(f"{device} on {link}: {message}" if link else f"{device}: {message}")
        self.device = device
        self.link = link
        self.details: dict[str, Any] = {**details, "link": link} if link else details


class NoFrameError(RuntimeError):
    """A camera delivered no image in the time allowed (the stream stalled, a file
    ended). The camera may deliver again later; an LED sensor reports the LEDs of that
    sequence as not found (``no_frame``)."""

    def __init__(self, camera: str, message: str, **details: Any) -> None:
        super().__init__(f"{camera}: {message}")
        self.camera = camera
        self.details: dict[str, Any] = details
