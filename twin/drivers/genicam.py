"""GenICam cameras (GigE Vision, USB3 Vision) behind :class:`twin.hal.Camera`, through a
GenTL producer and ``harvesters``.

A capture returns an image whose exposure began after the call (the LEDs were switched just
before it): the camera is triggered by software when it can be, else handled as a live
stream whose stale frames are dropped. Timeouts are in rig seconds
(:class:`twin.drivers.clock.WallClock`).
"""

from __future__ import annotations

import contextlib
import os
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from twin.drivers.camera import check_timeout
from twin.drivers.clock import WallClock
from twin.hal.devices import Camera
from twin.hal.errors import DeviceLostError, NoFrameError
from twin.hal.readings import CameraImage

DRAIN_TIMEOUT = 1e-3
"""Wall seconds a GenICam camera waits for each stale buffer it drops before a capture."""


def harvester_class() -> Any:
    """``harvesters.core.Harvester``.

    Raises:
        ImportError: ``harvesters`` is not installed (the message says how to install it).
    """
    try:
        from harvesters.core import Harvester
    except ImportError as exc:
        raise ImportError(
            "GenICam cameras need the harvesters package: pip install -e .[genicam]"
        ) from exc
    return Harvester


class GenICamCamera(Camera):
    """A GenICam camera (GigE Vision, USB3 Vision) through a GenTL producer and
    ``harvesters`` (the optional extra ``genicam``).

    When the camera has a software trigger (``TriggerSoftware``), every capture triggers
    one exposure: it begins after the call. Otherwise the camera runs free, the frames
    already delivered are dropped, and the second frame after the call is returned (the
    first may have been exposing when the LEDs switched).

    Args:
        producer: path of the vendor's GenTL producer (a ``.cti`` file).
        name: the camera's name in the rig.
        clock: the rig's clock.
        serial: the camera's serial number; None: by ``index``.
        index: which of the producer's cameras, when no serial is given.
        timeout_s: time a capture waits for its frame, rig s.

    Raises:
        ImportError: ``harvesters`` is not installed.
        twin.hal.errors.DeviceLostError: no such camera, or it cannot be opened.
    """

    def __init__(
        self,
        producer: str,
        *,
        name: str,
        clock: WallClock,
        serial: str | None = None,
        index: int = 0,
        timeout_s: float = 5.0,
    ) -> None:
        harvester = harvester_class()
        self._name = name
        self.link = f"{producer} (GenICam)"
        """Where and how the camera is reached, for messages: ``PRODUCER (GenICam)``."""
        self.clock = clock
        self.timeout_s = check_timeout(timeout_s)
        self._closed = False
        self._harvester = harvester()
        self._acquirer: Any = None
        try:
            self._harvester.add_file(os.fspath(producer))
            self._harvester.update()
            key: Any = {"serial_number": serial} if serial is not None else int(index)
            self._acquirer = self._harvester.create(key)
            nodes = self._acquirer.remote_device.node_map
            self._triggered = _try_software_trigger(nodes)
            self._size = (int(nodes.Width.value), int(nodes.Height.value))
            self._acquirer.start()
        except Exception as exc:
            self.close()
            which = f"serial {serial}" if serial is not None else f"index {index}"
            raise DeviceLostError(
                name, f"cannot open the camera ({which}): {exc}", link=self.link
            ) from exc

    @property
    def name(self) -> str:
        return self._name

    @property
    def image_size(self) -> tuple[int, int]:
        return self._size

    def capture(self) -> CameraImage:
        """One exposure begun after the call.

        Raises:
            twin.hal.errors.NoFrameError: no frame within ``timeout_s``.
            twin.hal.errors.DeviceLostError: the camera is closed or stopped answering.
        """
        if self._closed or self._acquirer is None:
            raise DeviceLostError(self._name, "the camera is closed", link=self.link)
        wait = self.clock.wall(self.timeout_s)
        deadline = time.monotonic() + wait
        try:
            # Drop what was exposed before the call (a timeout of 0 would wait for ever).
            while (stale := self._acquirer.try_fetch(timeout=DRAIN_TIMEOUT)) is not None:
                stale.queue()
            if self._triggered:
                self._acquirer.remote_device.node_map.TriggerSoftware.execute()
                wanted = 1
            else:
                wanted = 2
            for k in range(wanted):
                left = deadline - time.monotonic()
                buffer = self._acquirer.try_fetch(timeout=max(left, DRAIN_TIMEOUT))
                if buffer is None:
                    raise NoFrameError(
                        self._name, f"no frame within {self.timeout_s} s", timeout_s=self.timeout_s
                    )
                with buffer:
                    if k + 1 < wanted:
                        continue
                    stamp = self.clock.now()
                    component = buffer.payload.components[0]
                    image = _component_image(component)
        except (NoFrameError, DeviceLostError):
            raise
        except Exception as exc:
            raise DeviceLostError(
                self._name, f"connection lost: the camera failed: {exc}", link=self.link
            ) from exc
        return CameraImage(self._name, stamp, image)

    def close(self) -> None:
        """Stop acquiring and release the camera and the producer. Twice is harmless."""
        if self._closed:
            return
        self._closed = True
        if self._acquirer is not None:
            with contextlib.suppress(Exception):
                self._acquirer.stop()
            with contextlib.suppress(Exception):
                self._acquirer.destroy()
            self._acquirer = None
        with contextlib.suppress(Exception):
            self._harvester.reset()


def _try_software_trigger(nodes: Any) -> bool:
    """Put the camera in software-trigger mode if it has one; whether it did."""
    with contextlib.suppress(Exception):
        nodes.TriggerSelector.value = "FrameStart"
    try:
        nodes.TriggerMode.value = "On"
        nodes.TriggerSource.value = "Software"
        return hasattr(nodes, "TriggerSoftware")
    except Exception:
        with contextlib.suppress(Exception):
            nodes.TriggerMode.value = "Off"
        return False


def _component_image(component: Any) -> NDArray:
    """A harvesters image component as an (H, W) or (H, W, 3) copy."""
    h, w = int(component.height), int(component.width)
    data = np.asarray(component.data)
    channels = data.size // (h * w)
    image = data.reshape(h, w) if channels == 1 else data.reshape(h, w, channels)[..., :3]
    return np.array(image)  # the buffer is handed back to the producer
