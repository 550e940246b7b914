"""The GenICam camera driver against a stand-in for ``harvesters``: one triggered exposure
after the call, stale buffers handed back, a missing frame and a missing package named."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from twin.drivers.clock import WallClock
from twin.drivers.genicam import GenICamCamera
from twin.hal.errors import NoFrameError


def test_genicam_without_harvesters_says_how_to_install(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "harvesters", None)
    monkeypatch.setitem(sys.modules, "harvesters.core", None)
    with pytest.raises(ImportError, match=r"pip install -e \.\[genicam\]"):
        GenICamCamera("producer.cti", name="gige", clock=WallClock())


class _Node:
    def __init__(self, value: object = None) -> None:
        self.value = value


class _FakeBuffer:
    def __init__(self, acquirer: _FakeAcquirer, value: int) -> None:
        self.acquirer = acquirer
        data = np.full(acquirer.height * acquirer.width, value, np.uint8)
        component = types.SimpleNamespace(width=acquirer.width, height=acquirer.height, data=data)
        self.payload = types.SimpleNamespace(components=[component])

    def queue(self) -> None:
        self.acquirer.queued += 1

    def __enter__(self) -> _FakeBuffer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.queue()


class _FakeAcquirer:
    """A triggered camera: each TriggerSoftware exposes one frame of ``scene``."""

    width, height = 8, 6

    def __init__(self, stale: int) -> None:
        self.scene = 50
        self.queued = 0
        self.started = False
        self.destroyed = False
        self.pending = [_FakeBuffer(self, 1) for _ in range(stale)]
        trigger = types.SimpleNamespace(execute=self._expose)
        self.remote_device = types.SimpleNamespace(
            node_map=types.SimpleNamespace(
                Width=_Node(self.width),
                Height=_Node(self.height),
                TriggerSelector=_Node(),
                TriggerMode=_Node(),
                TriggerSource=_Node(),
                TriggerSoftware=trigger,
            )
        )

    def _expose(self) -> None:
        self.pending.append(_FakeBuffer(self, self.scene))

    def try_fetch(self, *, timeout: float) -> _FakeBuffer | None:
        assert timeout > 0, "harvesters waits for ever on a timeout of 0"
        return self.pending.pop(0) if self.pending else None

    def start(self) -> None:
        self.started = True

    def stop(self) -> None:
        self.started = False

    def destroy(self) -> None:
        self.destroyed = True


def _fake_harvesters(monkeypatch, acquirer: _FakeAcquirer) -> dict[str, object]:
    seen: dict[str, object] = {}

    class Harvester:
        def add_file(self, path: str) -> None:
            seen["producer"] = path

        def update(self) -> None:
            pass

        def create(self, key: object) -> _FakeAcquirer:
            seen["key"] = key
            return acquirer

        def reset(self) -> None:
            seen["reset"] = True

    core = types.ModuleType("harvesters.core")
    core.Harvester = Harvester
    package = types.ModuleType("harvesters")
    package.core = core
    monkeypatch.setitem(sys.modules, "harvesters", package)
    monkeypatch.setitem(sys.modules, "harvesters.core", core)
    return seen


def test_genicam_triggers_an_exposure_after_the_call(monkeypatch) -> None:
    acquirer = _FakeAcquirer(stale=3)
    seen = _fake_harvesters(monkeypatch, acquirer)
    cam = GenICamCamera("vendor.cti", name="gige", clock=WallClock(), serial="A1")
    try:
        assert seen["producer"] == "vendor.cti"
        assert seen["key"] == {"serial_number": "A1"}
        assert acquirer.started
        assert acquirer.remote_device.node_map.TriggerSource.value == "Software"
        assert cam.image_size == (8, 6)
        acquirer.scene = 77
        shot = cam.capture()
        assert shot.image.shape == (6, 8)
        assert np.all(shot.image == 77)  # not one of the three frames exposed before
        assert acquirer.queued == 4  # the stale buffers and the used one went back
    finally:
        cam.close()
        cam.close()
    assert acquirer.destroyed
    assert seen["reset"]


def test_genicam_without_a_frame_raises_no_frame(monkeypatch) -> None:
    acquirer = _FakeAcquirer(stale=0)
    acquirer.remote_device.node_map.TriggerSoftware.execute = lambda: None  # never exposes
    _fake_harvesters(monkeypatch, acquirer)
    cam = GenICamCamera("vendor.cti", name="gige", clock=WallClock(), timeout_s=0.2)
    try:
        with pytest.raises(NoFrameError, match=r"gige: no frame within 0\.2 s"):
            cam.capture()
    finally:
        cam.close()
