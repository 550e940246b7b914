"""A run whose campaign is aborted (a device lost): the abort names the device and its
link in the results and on the console, and every planned visit it never made is listed
as skipped, with the abort as its reason."""

from __future__ import annotations

from pathlib import Path

import pytest
from rich.console import Console

from twin.cli.run import print_results
from twin.hal.errors import DeviceLostError
from twin.hal.wrappers import MobileBaseWrapper, wrapped
from twin.record import read_log
from twin.run.runner import run_scenario

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / "scenarios" / "smoke.toml"
LOST = "child1 on /dev/ttyUSB7 (ARCOS): connection lost (test)"


class Unplugged(MobileBaseWrapper):
    """A base whose link breaks at the first drive after ``broken()`` turns true."""

    def __init__(self, inner, broken) -> None:
        super().__init__(inner)
        self.broken = broken

    def drive_to(self, goal_xy, goal_yaw=None):
        if self.broken():
            raise DeviceLostError(
                self.name,
                "connection lost (test)",
                link="/dev/ttyUSB7 (ARCOS)",
                port="/dev/ttyUSB7",
            )
        return self.inner.drive_to(goal_xy, goal_yaw)


@pytest.fixture(scope="module")
def two_visits(tmp_path_factory) -> Path:
    """The smoke room with cam1 calibrated from two stations."""
    text = SMOKE.read_text()
    one = 'visits = [{ camera = "cam1", station = [0.5, 0.0] }]'
    assert one in text
    two = one.replace("}]", '}, { camera = "cam1", station = [2.0, 0.0] }]')
    path = tmp_path_factory.mktemp("scenario") / "two_visits.toml"
    path.write_text(text.replace(one, two))
    return path


@pytest.mark.parametrize("calibrated_before", [0, 1])
def test_the_visits_an_aborted_campaign_never_made_are_skipped_with_the_abort(
    two_visits, tmp_path, calibrated_before
):
    calibrated = [0]

    def adapt(sim):
        def broken() -> bool:
            return calibrated[0] >= calibrated_before

        return wrapped(sim.rig, base=lambda b: Unplugged(b, broken) if b.name == "child1" else b)

    def progress(p) -> None:
        calibrated[0] = p.calibrated

    results = run_scenario(
        two_visits,
        tmp_path / "run",
        fidelity="geometric",
        report=False,
        adapt_rig=adapt,
        progress=progress,
    )
    made = [(c["camera"], c["visit"]) for c in results["calibrations"]]
    assert made == [("cam1", 1)][:calibrated_before]
    skipped = results["skipped_visits"]
    assert [(s["camera"], s["visit"]) for s in skipped] == [
        ("cam1", k) for k in range(calibrated_before + 1, 3)
    ]
    assert [s["station"] for s in skipped] == [[0.5, 0.0], [2.0, 0.0]][calibrated_before:]
    for s in skipped:
        assert s["reason"] == "campaign_aborted"
        assert s["message"] == f"the campaign was aborted: a device is lost: {LOST}"
    assert results["aborted"] == f"a device is lost: {LOST}"
    assert results["failures"]["device_lost"] == 1
    # The log holds them: a replay of it gives the same.
    lost = [
        m.data
        for m in read_log(tmp_path / "run" / "log.mcap").messages
        if m.topic == "/campaign/failure" and m.data["kind"] == "device_lost"
    ]
    assert lost[0]["message"] == LOST
    assert lost[0]["details"]["link"] == "/dev/ttyUSB7 (ARCOS)"
    # The console says it in one line, and each visit skipped.
    console = Console(record=True, width=200, force_terminal=False)
    print_results(results, console)
    text = console.export_text()
    assert f"campaign aborted: a device is lost: {LOST}\n" in text
    assert "skipped cam1 visit 2: campaign_aborted (the campaign was aborted: " in text


def test_a_campaign_that_is_not_aborted_skips_nothing_it_made(tmp_path):
    # Without the reference data set (half the run; no visit depends on it).
    smoke = tmp_path / "smoke.toml"
    smoke.write_text(SMOKE.read_text() + "\n[campaign]\nreference_cameras = []\n")
    results = run_scenario(smoke, tmp_path / "run", fidelity="geometric", report=False)
    assert results["aborted"] is None
    assert results["skipped_visits"] == []
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == [("cam1", 1)]
