"""What a real device's failures do to the campaign: a busy or slow instrument is asked
again with the same aim, an error code of its own is recorded, a lost device ends the
campaign cleanly with everything measured before it kept."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.campaign.records import CALIBRATION, POINT
from twin.hal.errors import DeviceLostError
from twin.hal.wrappers import MobileBaseWrapper, TotalStationWrapper, wrapped
from twin.instruments.errors import (
    DistanceMeasurementError,
    InstrumentBusyError,
    InstrumentFaultError,
    InstrumentTimeoutError,
)
from twin.record import read_log
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


class Flaky(TotalStationWrapper):
    """Every ``every``-th measurement fails with ``error`` (after the aim was set); the aims
    of each measurement are kept."""

    def __init__(self, inner, error: type[Exception], every: int) -> None:
        super().__init__(inner)
        self.error, self.every = error, every
        self.calls = 0
        self.aims: list[tuple[float, ...]] = []

    def point(self, target_level) -> None:
        self.aims.append(tuple(float(v) for v in target_level))
        self.inner.point(target_level)

    def measure(self):
        self.calls += 1
        if self.calls % self.every == 0:
            raise self.error("the instrument says no (test)", code=1234)
        return self.inner.measure()


@pytest.mark.parametrize(
    "error", [InstrumentBusyError, InstrumentTimeoutError, DistanceMeasurementError]
)
def test_a_busy_or_slow_instrument_is_asked_again_with_the_same_aim(tmp_path, error):
    flaky: list[Flaky] = []

    def adapt(sim):
        return wrapped(
            sim.rig, total_station=lambda s: flaky.append(Flaky(s, error, 7)) or flaky[-1]
        )

    results = run_scenario(
        SMOKE, tmp_path, fidelity="geometric", report=False, adapt_rig=adapt, seed=3
    )
    station = flaky[0]
    failed = station.calls // 7
    assert failed >= 5
    assert results["failures"][error("").reason.value] == failed
    # The measurement after each failure was aimed where the failed one was.
    repeated = sum(1 for a, b in zip(station.aims, station.aims[1:], strict=False) if a == b)
    assert repeated >= failed
    assert [c["camera"] for c in results["calibrations"]] == ["cam1"]


def test_an_error_code_of_the_instruments_own_is_recorded_not_retried(tmp_path):
    flaky: list[Flaky] = []

    def adapt(sim):
        return wrapped(
            sim.rig,
            total_station=lambda s: flaky.append(Flaky(s, InstrumentFaultError, 11)) or flaky[-1],
        )

    results = run_scenario(
        SMOKE, tmp_path, fidelity="geometric", report=False, adapt_rig=adapt, seed=3
    )
    assert results["failures"]["instrument_fault"] == flaky[0].calls // 11 >= 3


class Unplugged(MobileBaseWrapper):
    """A base whose link breaks at its ``after``-th drive."""

    def __init__(self, inner, after: int) -> None:
        super().__init__(inner)
        self.after, self.drives = after, 0

    def drive_to(self, goal_xy, goal_yaw=None):
        self.drives += 1
        if self.drives >= self.after:
            raise DeviceLostError(self.name, "the serial line closed (test)", port="/dev/null")
        return self.inner.drive_to(goal_xy, goal_yaw)


def test_a_lost_device_ends_the_campaign_and_keeps_what_was_measured(tmp_path):
    def adapt(sim):
        child = next(iter(sim.rig.children))
        return wrapped(sim.rig, base=lambda b: Unplugged(b, 4) if b.name == child else b)

    results = run_scenario(
        SMOKE, tmp_path, fidelity="geometric", report=False, adapt_rig=adapt, seed=3
    )
    assert results["failures"]["device_lost"] == 1
    assert results["failures"]["campaign_aborted"] == 1
    assert results["complete"]  # the run ended cleanly: its summary is written
    assert results["calibrations"] == []
    log = read_log(tmp_path / "log.mcap")
    assert log.complete
    # The reference data taken before the loss is in the log.
    assert sum(m.topic == POINT for m in log.messages) > 0
    assert not any(m.topic == CALIBRATION for m in log.messages)
    lost = [
        m.data
        for m in log.messages
        if m.topic.endswith("failure") and m.data["kind"] == "device_lost"
    ]
    assert lost
    assert lost[0]["details"]["device"] == "child1"
    assert lost[0]["details"]["port"] == "/dev/null"
