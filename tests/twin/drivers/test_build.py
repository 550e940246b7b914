"""Opening a rig file's devices: a device that opens but cannot say what it is, or a part
built on an open link that fails, is named, and everything opened before is closed again,
by ``twin run --rig`` (build_rig) and by ``twin devices`` (probe_rig) alike."""

from __future__ import annotations

from pathlib import Path

import pytest

import twin.drivers.build as build
import twin.drivers.probe as probe
from twin.drivers.build import DeviceConnectError, build_rig
from twin.drivers.probe import probe_rig
from twin.drivers.rig_file import load_rig_file
from twin.hal.errors import DeviceLostError
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "examples" / "paper_rig.toml"
HALL = ROOT / "scenarios" / "paper_hall.toml"


class FakeDevice:
    """Stands for any driver: records whether it was closed; ``identify`` may fail."""

    def __init__(self, name: str, opened: list[FakeDevice], fails: bool = False) -> None:
        self.name, self.fails, self.closed = name, fails, False
        opened.append(self)

    def identify(self) -> dict[str, object]:
        if self.fails:
            raise DeviceLostError(self.name, "no answer to the identity request")
        return {"name": self.name}

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def opened(monkeypatch: pytest.MonkeyPatch) -> list[FakeDevice]:
    """Every device open_* returned; the total station fails to identify itself."""
    out: list[FakeDevice] = []
    for module in (build, probe):
        monkeypatch.setattr(
            module,
            "open_total_station",
            lambda device, clock, noise: FakeDevice("total_station", out, fails=True),
        )
        monkeypatch.setattr(
            module, "open_connection", lambda device, clock: FakeDevice(device.name, out)
        )
    return out


def test_a_station_that_cannot_identify_itself_is_named_and_closed(
    opened: list[FakeDevice],
) -> None:
    with pytest.raises(DeviceConnectError, match=r"total station at .*no answer"):
        build_rig(load_rig_file(EXAMPLE), load_scenario(HALL))
    assert [d.name for d in opened] == ["total_station"]
    assert all(d.closed for d in opened)


def test_a_base_that_fails_on_an_open_link_closes_every_device(
    opened: list[FakeDevice], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(
        build,
        "open_total_station",
        lambda device, clock, noise: FakeDevice("total_station", opened),
    )

    def no_base(connection: FakeDevice, device: object, start: object) -> None:
        raise ValueError(f"start_pose must be a finite (x, y, yaw), got {start!r}")

    monkeypatch.setattr(build, "open_base", no_base)
    with pytest.raises(DeviceConnectError, match=r"robot 'parent' at .*start_pose"):
        build_rig(load_rig_file(EXAMPLE), load_scenario(HALL))
    assert [d.name for d in opened] == ["total_station", "parent"]
    assert all(d.closed for d in opened)


def test_the_probe_closes_a_device_that_cannot_identify_itself(
    opened: list[FakeDevice],
) -> None:
    reports = probe_rig(load_rig_file(EXAMPLE).model_copy(update={"cameras": ()}), blink=False)
    assert [(r.device, r.ok) for r in reports] == [
        ("total_station", False),
        ("parent", True),
        ("child1", True),
        ("child2", True),
    ]
    assert "no answer to the identity request" in reports[0].facts["error"]
    assert all(d.closed for d in opened)


@pytest.mark.parametrize("link", ["/dev/pts/5 (GeoCOM)", ""])
def test_a_device_lost_while_opening_is_named_once_with_its_link(
    opened: list[FakeDevice], monkeypatch: pytest.MonkeyPatch, link: str
) -> None:
    def lost(device: object, clock: object, noise: object) -> None:
        raise DeviceLostError("total_station", "connection lost", link=link)

    monkeypatch.setattr(build, "open_total_station", lost)
    with pytest.raises(DeviceConnectError) as caught:
        build_rig(load_rig_file(EXAMPLE), load_scenario(HALL))
    message = str(caught.value)
    assert message.count("connection lost") == 1
    if link:
        assert message == "total_station on /dev/pts/5 (GeoCOM): connection lost"
    else:
        assert message.startswith("total station at ")
