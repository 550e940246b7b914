"""The campaign over the devices' real protocols: ``twin emulate`` plays the hardware, the
drivers talk to it, and the results agree with the twin's own run of the same seed.

Also: the drivers' rig keeps the interface's promises (``check_rig``) against the
emulators; Ctrl-C during a drive stops every robot and keeps the log; a killed run's log
reads back and the watchdog stops the robot it left driving.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from twin.drivers.build import build_rig
from twin.drivers.rig_file import load_rig_file, write_rig_file
from twin.emulators.emulation import start_emulation, truth_file
from twin.emulators.geocom_faults import Fault
from twin.hal.conformance import check_rig
from twin.montecarlo.prediction import predictions_from_log
from twin.record import read_log
from twin.run.hardware_run import run_on_rig
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
SCALE = 30.0
"""Rig seconds per wall second in these tests: a drive of 3 s takes 0.1 s."""
FPS = 100.0
SEED = 11
WITHOUT_REFERENCE = "\n[campaign]\nreference_cameras = []\n"
"""What the smoke scenario's file gets for the runs that go to the end: no reference data
set (70 points at the start that no assertion here reads), which takes their campaign's
protocol traffic, and so their time, to less than half."""


def _without_reference(tmp_path: Path) -> Path:
    """The smoke scenario without its reference data set, as a file in ``tmp_path``."""
    path = tmp_path / "smoke.toml"
    path.write_text(SMOKE.read_text() + WITHOUT_REFERENCE)
    return path


def _wait_for(condition, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.01)


def _twin(*args: str) -> list[str]:
    return [sys.executable, "-m", "twin.cli", *args]


def test_the_campaign_over_the_protocols_agrees_with_the_twin(tmp_path):
    smoke = _without_reference(tmp_path)
    rig_path = tmp_path / "rig.toml"
    emulate = subprocess.Popen(
        _twin(
            "emulate",
            str(smoke),
            "--seed",
            str(SEED),
            "--time-scale",
            str(SCALE),
            "--fps",
            str(FPS),
            "--rig-out",
            str(rig_path),
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        cwd=ROOT,
    )
    try:
        _wait_for(rig_path.exists, 60.0, "twin emulate's rig file")
        over = run_on_rig(smoke, rig_path, tmp_path / "rig-run", report=False)
    finally:
        emulate.send_signal(signal.SIGINT)
        out, _ = emulate.communicate(timeout=30)
    assert emulate.returncode == 0, out.decode()
    assert b"emulators stopped" in out
    twin = run_scenario(smoke, tmp_path / "twin-run", fidelity="geometric", seed=SEED, report=False)

    assert over["fidelity"] == "hardware"
    cams = [(c["camera"], c["visit"]) for c in over["calibrations"]]
    assert cams == [(c["camera"], c["visit"]) for c in twin["calibrations"]] == [("cam1", 1)]
    a, b = over["calibrations"][0], twin["calibrations"][0]
    assert a["points"] == b["points"]
    # The emulated world's truth reached the run: its errors are against the truth.
    assert a["truth"]["position_mm"] == pytest.approx(b["truth"]["position_mm"], abs=1e-6)
    # Two independent runs of the same camera: their positions differ by their predicted
    # errors (the covariance the campaign propagates: the parent's pose at the station,
    # the pixel noise and the LED points' own errors; 3 sigma of a 3D normal difference,
    # which a consistent pair exceeds with probability 6e-6), and so do their errors
    # against the truth.
    sc = load_scenario(smoke)
    pixel = {c.name: sc.projected_led_px(c.name) for c in sc.cameras}
    (pa,), _ = predictions_from_log(read_log(tmp_path / "rig-run" / "log.mcap").messages)
    (pb,), _ = predictions_from_log(read_log(tmp_path / "twin-run" / "log.mcap").messages, pixel)
    both_mm = 1e3 * float(np.hypot(pa.rms_m, pb.rms_m))
    diff = np.subtract(a["parameters"]["position_mm"], b["parameters"]["position_mm"])
    assert np.linalg.norm(diff) < 3 * both_mm, (diff, both_mm)
    error_a, error_b = a["truth"]["position_error_mm"], b["truth"]["position_error_mm"]
    assert abs(error_a - error_b) < 3 * both_mm
    assert abs(a["sigma_px"] - b["sigma_px"]) < 0.5 * b["sigma_px"]
    # Every reading went through the drivers and is in the log, with what each device said.
    log = read_log(tmp_path / "rig-run" / "log.mcap")
    assert log.complete
    devices = {m.data["device"]: m.data for m in log.messages if m.topic == "/rig/device"}
    assert devices["total_station"]["name"] == "TS16 R500"
    assert devices["child1"]["subtype"] == "p3dx-sh"
    assert devices["cam1"]["resolution"] == [320, 240]


@pytest.fixture
def emulation():
    em = start_emulation(SMOKE, time_scale=SCALE, camera_fps=FPS, seed=SEED)
    try:
        yield em
    finally:
        em.close()


@pytest.fixture
def emulation_without_reference(tmp_path):
    """The emulators of the smoke scenario without its reference data set, and its file."""
    smoke = _without_reference(tmp_path)
    em = start_emulation(smoke, time_scale=SCALE, camera_fps=FPS, seed=SEED)
    try:
        yield em, smoke
    finally:
        em.close()


def test_the_drivers_rig_keeps_the_interface_against_the_emulators(emulation, tmp_path):
    rig_path = emulation.write_rig_file(tmp_path / "rig.toml")
    sc = load_scenario(SMOKE)
    devices = build_rig(load_rig_file(rig_path), sc)
    sim = emulation.sim
    with emulation.lock:
        position, rotation = sim.world.instrument_pose(sim.rig.parent.name)
        cubes = np.vstack([sim.world.marker_points(c)[0] for c in sim.rig.children])
    prisms = (cubes - position) @ rotation
    try:
        report = check_rig(devices.rig, prisms_level=prisms, cameras=["cam1"], close=False)
    finally:
        devices.close()
    # Every prism in the parent's sight was locked through GeoCOM and landed on its prism;
    # every base drove twice over ARCOS; each child's LEDs were seen over MJPEG.
    assert report.shots == 6
    assert report.drives == 6
    assert report.observations == 2
    assert report.leds_found == 8
    assert report.images == 1


def test_the_rig_file_written_reads_back_as_written(emulation, tmp_path):
    import tomllib

    path = emulation.write_rig_file(tmp_path / "rig.toml")
    assert tomllib.loads(path.read_text()) == json.loads(
        json.dumps(emulation.rig_file("rig.truth.json"))
    )
    rig = load_rig_file(path)
    assert rig.time_scale == SCALE
    assert rig.emulator is not None
    truth = json.loads((tmp_path / rig.emulator.truth).read_text())
    assert set(truth["cameras"]) == {"cam1"}


def _start_run(rig_path: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(
        _twin("run", str(SMOKE), "--rig", str(rig_path), "--out", str(out), "--no-report"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def _moving(emulation) -> list[str]:
    return [name for name, robot in emulation.robots.items() if robot.body.moving]


def _led_switches(emulation) -> int:
    """How many times the children's LEDs were switched (ARCOS DIGOUT) so far."""
    return sum(
        sum(1 for number, _ in list(robot.commands) if number == 30)
        for name, robot in emulation.robots.items()
        if name != "parent"
    )


def _data_stop_drive(emulation) -> bool:
    """A child drives (the campaign is past its start and taking data)."""
    return any(n != "parent" for n in _moving(emulation))


def test_ctrl_c_during_a_drive_stops_every_robot_and_keeps_the_log(emulation, tmp_path):
    rig_path = emulation.write_rig_file(tmp_path / "rig.toml")
    run = _start_run(rig_path, tmp_path / "run")
    try:
        _wait_for(lambda: _data_stop_drive(emulation) or run.poll() is not None, 60, "a drive")
        assert run.poll() is None, run.stdout.read().decode()
        run.send_signal(signal.SIGINT)
        out, _ = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    assert run.returncode == 130, out.decode()
    assert b"interrupted" in out
    # Stopped by the driver (a stop, then CLOSE), not left to the watchdog.
    _wait_for(lambda: not _moving(emulation), 5.0, "the robots to stop")
    for name, robot in emulation.robots.items():
        assert not robot.session_open, name
        assert robot.watchdog_trips == 0, name
    log = read_log(tmp_path / "run" / "log.mcap")
    assert log.complete  # closed properly on the way out
    topics = {m.topic for m in log.messages}
    assert {"/run/meta", "/total_station/inclination", "/campaign/stage"} <= topics


def test_a_killed_runs_log_reads_back_and_the_watchdog_stops_the_robot(emulation, tmp_path):
    rig_path = emulation.write_rig_file(tmp_path / "rig.toml")
    run = _start_run(rig_path, tmp_path / "run")
    try:
        _wait_for(lambda: _data_stop_drive(emulation) or run.poll() is not None, 60, "a drive")
        assert run.poll() is None, run.stdout.read().decode()
        driving = _moving(emulation)
        run.send_signal(signal.SIGKILL)
        run.wait(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    # Nobody said stop: the watchdog (2 rig seconds without a command) stops the robot.
    _wait_for(lambda: not _moving(emulation), 5.0, "the watchdog to stop the robots")
    assert sum(emulation.robots[n].watchdog_trips for n in driving) >= 1
    log = read_log(tmp_path / "run" / "log.mcap")
    assert not log.complete
    # What was handed to the system before the kill (every 8 records) reads back.
    assert len(log.messages) >= 8
    assert log.messages[0].topic == "/run/meta"


LINK = re.compile(r"(parent|child1|child2|total_station|cam1) on \S+ \((ARCOS|GeoCOM|OpenCV)\)")
"""How a lost device is named: the device, its port or source, its protocol."""

VIDEO_LOG = re.compile(r"\[(tcp|http|mjpeg)[^\]]* @ 0x|\[ ?(WARN|ERROR|INFO):")
"""A line of FFmpeg's or OpenCV's own logging."""


def test_devices_gone_mid_run_end_it_naming_the_device_without_video_warnings(emulation, tmp_path):
    rig_path = emulation.write_rig_file(tmp_path / "rig.toml")
    run = _start_run(rig_path, tmp_path / "run")
    try:
        _wait_for(lambda: _data_stop_drive(emulation) or run.poll() is not None, 60, "a drive")
        assert run.poll() is None, run.stdout.read().decode()
        emulation.close()  # every device gone at once, as when the emulator is killed
        out, _ = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    text = out.decode()
    assert run.returncode == 1, text
    (aborted,) = [line for line in text.splitlines() if line.startswith("campaign aborted:")]
    assert "a device is lost: " in aborted
    assert LINK.search(aborted), aborted
    assert "skipped cam1 visit 1: campaign_aborted (the campaign was aborted: " in text
    assert not [line for line in text.splitlines() if VIDEO_LOG.search(line)], text
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert LINK.search(results["aborted"])
    assert [(s["camera"], s["visit"], s["reason"]) for s in results["skipped_visits"]] == [
        ("cam1", 1, "campaign_aborted")
    ]
    assert read_log(tmp_path / "run" / "log.mcap").complete


def _drop_child1(em) -> None:
    em.robots["child1"].faults.drop_link = True


def _silent_instrument(em) -> None:
    em.total_station.faults.set(Fault.SILENT)


SILENT_TIMEOUT_WALL = 1.0
"""The instrument's timeout in the silent instrument's run, wall s: it is found lost after
three unanswered requests, 3 s rather than the rig file's 7.5 s (a reply the emulator
sends takes milliseconds)."""


def _unknown_code(em) -> None:
    em.total_station.faults.set(Fault.CODE, code=4242, times=2)


@pytest.mark.parametrize(
    ("inject", "expected", "calibrated", "reference"),
    [
        (_drop_child1, {"device_lost": 1, "campaign_aborted": 1}, False, True),
        (_silent_instrument, {"device_lost": 1, "campaign_aborted": 1}, False, True),
        (_unknown_code, {"instrument_fault": 2}, True, False),
    ],
    ids=["robot-unplugged", "instrument-silent", "unknown-return-code"],
)
def test_a_device_fault_mid_run_is_recorded_and_the_run_ends_cleanly(
    tmp_path, inject, expected, calibrated, reference
):
    # The faults that end the run come during the smoke scenario's reference data set; the
    # one the run goes on after comes during the camera's data set, in the scenario without
    # the reference data set (the run goes to its end, and that set would double its time).
    smoke = SMOKE if reference else _without_reference(tmp_path)
    emulation = start_emulation(smoke, time_scale=SCALE, camera_fps=FPS, seed=SEED)
    try:
        _fault_mid_run(emulation, smoke, tmp_path, inject, expected, calibrated)
    finally:
        emulation.close()


def _fault_mid_run(emulation, smoke, tmp_path, inject, expected, calibrated) -> None:
    rig_path = emulation.write_rig_file(tmp_path / "rig.toml")
    if inject is _silent_instrument:
        rig = emulation.rig_file(truth_file(rig_path).name)
        rig["total_station"]["timeout_s"] = SILENT_TIMEOUT_WALL * SCALE
        write_rig_file(rig_path, rig)
    injected: list[float] = []

    def fault_when_taking_data() -> None:
        # Two LED sequences seen (6 switches each): data points have been taken.
        end = time.monotonic() + 90
        while _led_switches(emulation) < 12 and time.monotonic() < end:
            time.sleep(0.005)
        inject(emulation)
        injected.append(time.monotonic())

    thread = threading.Thread(target=fault_when_taking_data, daemon=True)
    thread.start()
    results = run_on_rig(smoke, rig_path, tmp_path / "run", report=False)
    thread.join(timeout=5)
    assert injected, "the fault was not injected"
    for kind, count in expected.items():
        assert results["failures"].get(kind, 0) == count, results["failures"]
    assert bool(results["calibrations"]) == calibrated
    assert results["complete"]
    log = read_log(tmp_path / "run" / "log.mcap")
    assert log.complete
    # What was measured before the fault is in the log: the data points taken so far.
    points = [m for m in log.messages if m.topic == "/campaign/point"]
    assert points
    if kind := next((k for k in expected if k == "device_lost"), None):
        lost = [m.data for m in log.messages if m.topic == "/campaign/failure"]
        assert any(f["kind"] == kind for f in lost)
    if inject is _unknown_code:
        faults = [
            m.data["message"]
            for m in log.messages
            if m.topic == "/campaign/failure" and m.data["kind"] == "instrument_fault"
        ]
        assert all("4242" in f and "unknown" in f for f in faults), faults


def test_the_render_fidelity_serves_rendered_frames_in_which_the_leds_are_found(tmp_path):
    from twin.drivers.probe import probe_rig

    em = start_emulation(SMOKE, fidelity="render", time_scale=SCALE, camera_fps=30.0)
    try:
        rig = load_rig_file(em.write_rig_file(tmp_path / "rig.toml"))
        reports = {(r.kind, r.device): r for r in probe_rig(rig)}
    finally:
        em.close()
    assert all(r.ok for r in reports.values()), reports
    # Both children stand in cam1's view at the start, child1 near the image's right edge:
    # a blink in the rendered images finds their LEDs (one may be cut by the edge).
    found = [int(reports["LEDs", c].facts["found"].split()[0]) for c in ("child1", "child2")]
    assert min(found) >= 2
    assert sum(found) >= 6
