"""The ARCOS driver against the emulated Pioneers of the smoke room, over TCP and a pty:
drives land where the world says the robot is, pose fixes hold, LEDs switch, stalls,
e-stops, time-outs, noisy lines and lost robots end as the interface promises."""

from __future__ import annotations

import dataclasses
import math
import socket
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.drivers.arcos import ArcosBase, ArcosLeds, Command, PioneerConnection
from twin.drivers.arcos.protocol import command
from twin.drivers.clock import WallClock
from twin.emulators.arcos import ArcosFaults, PioneerEmulator
from twin.emulators.links import PtyLink, TcpLink
from twin.emulators.pioneer_body import PioneerBody
from twin.hal.devices import MarkerLeds
from twin.hal.errors import DeviceLostError
from twin.hal.readings import DriveStatus, LedSwitch
from twin.scenario import load_scenario
from twin.sim.rig.frames import WorldFrame
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"
SCALE = 10.0
"""Rig seconds per wall second: a 2 m drive takes under a wall second."""


class RecordingLeds(MarkerLeds):
    """LEDs that remember what they were switched to."""

    def __init__(self, count: int = 4) -> None:
        self.seen: list[tuple[bool, ...]] = []
        self._count = count

    @property
    def child(self) -> str:
        return "child1"

    @property
    def count(self) -> int:
        return self._count

    def switch(self, on: Sequence[bool]) -> LedSwitch:
        self.seen.append(tuple(on))
        return LedSwitch("child1", 0.0, tuple(on))

    def close(self) -> None:
        pass


def _world():
    sc = load_scenario(SMOKE)
    world = build_world(sc)
    world.run(0.5)  # at rest on its wheels before W is taken
    position, rotation = world.instrument_pose(sc.robots.parent.name)
    return world, WorldFrame.from_instrument(position, rotation)


@pytest.fixture
def rig():
    """A factory of (world, emulator, connection, base); everything it made is closed."""
    opened: list = []

    def make(
        link: str = "pty",
        robot: str = "child1",
        *,
        connect: bool = True,
        faults: ArcosFaults | None = None,
        leds: MarkerLeds | None = None,
        led_bits: Sequence[int] = (),
        unreachable=(),
        timeout_s: float = 5.0,
        **base_args,
    ) -> SimpleNamespace:
        world, frame = _world()
        model = "p3at" if robot == "parent" else "p3dx"
        clock = WallClock(SCALE)
        body = PioneerBody(
            world,
            robot,
            frame,
            threading.RLock(),
            stopping=world.scenario.noise.stopping,
            rng=np.random.default_rng(7),
            unreachable=unreachable,
        )
        emulator = PioneerEmulator(
            body,
            model=model,
            time=clock,
            link=TcpLink() if link == "tcp" else PtyLink(),
            leds=leds,
            led_bits=led_bits,
            faults=faults,
        )
        opened.append(emulator)
        emulator.start()
        if not connect:
            return SimpleNamespace(world=world, emulator=emulator, clock=clock)
        conn = PioneerConnection(
            emulator.address, model=model, clock=clock, name=robot, timeout_s=timeout_s
        )
        opened.append(conn)
        start = frame.pose(world.robot_pose(robot))
        base = ArcosBase(
            conn,
            name=robot,
            start_pose=(float(start[0]), float(start[1]), float(start[2])),
            **{"max_speed": 0.5, "max_turn_rate": 1.0, **base_args},
        )
        opened.append(base)

        def truth() -> np.ndarray:
            return frame.pose(world.robot_pose(robot))

        return SimpleNamespace(
            world=world,
            frame=frame,
            body=body,
            emulator=emulator,
            conn=conn,
            base=base,
            clock=clock,
            truth=truth,
            faults=emulator.faults,
        )

    try:
        yield make
    finally:
        for thing in reversed(opened):
            thing.close()
    for thing in opened:
        assert getattr(thing, "error", None) is None  # no emulator thread died


@pytest.mark.parametrize("link", ["tcp", "pty"])
def test_a_drive_lands_where_the_world_puts_the_robot(rig, link):
    r = rig(link)
    start = r.truth()
    goal = start[:2] + np.array([2.0, 0.3])
    result = r.base.drive_to(goal, goal_yaw=0.5)
    assert result.status is DriveStatus.REACHED, result.message
    assert result.goal[2] == 0.5
    odo = result.odometry
    assert math.hypot(odo.x - goal[0], odo.y - goal[1]) <= r.base.goal_tolerance + 1e-3
    assert abs(odo.yaw - 0.5) <= r.base.yaw_tolerance + 2e-3
    # The truth: the goal, within the tolerance and a few draws of the stopping error.
    stopping = r.world.scenario.noise.stopping
    truth = r.truth()
    assert np.linalg.norm(truth[:2] - goal) < r.base.goal_tolerance + 4 * stopping.sigma_xy * 1.5
    assert abs(truth[2] - 0.5) < r.base.yaw_tolerance + 4 * stopping.sigma_yaw
    assert 0 < result.duration < 60.0
    assert result.timestamp == pytest.approx(r.clock.now(), abs=5.0)
    # A drive to where it stands returns at once.
    wall = time.monotonic()
    again = r.base.drive_to([odo.x, odo.y])
    assert again.status is DriveStatus.REACHED
    assert math.isnan(again.goal[2])
    assert time.monotonic() - wall < 1.0
    assert r.conn.rejected == {
        "garbage_bytes": 0,
        "bad_checksum": 0,
        "truncated": 0,
        "malformed": 0,
    }


def test_set_pose_reanchors_odometry_and_later_drives(rig):
    r = rig("tcp")
    ident = r.conn.identify()
    assert ident == {"name": "child1", "type": "Pioneer", "subtype": "p3dx-sh", "battery_v": 13.0}
    r.base.set_pose(10.0, -4.0, 1.0)
    odo = r.base.odometry()
    assert (odo.x, odo.y, odo.yaw) == (10.0, -4.0, 1.0)  # exactly, not nearly
    r.conn.wait_for(lambda s: True)
    r.conn.wait_for(lambda s: True)
    odo = r.base.odometry()
    assert (odo.x, odo.y, odo.yaw) == (10.0, -4.0, 1.0)  # at rest: the same SIP pose
    r.base.set_pose(-0.1, 0.2, -3.0)
    odo = r.base.odometry()
    assert (odo.x, odo.y, odo.yaw) == (-0.1, 0.2, -3.0)
    r.base.set_pose(10.0, -4.0, 1.0)
    # In the new frame, 0.8 m ahead along its believed heading is 0.8 m ahead in truth.
    before = r.truth()
    goal = np.array([10.0 + 0.8 * math.cos(1.0), -4.0 + 0.8 * math.sin(1.0)])
    result = r.base.drive_to(goal)
    assert result.reached
    moved = r.truth()[:2] - before[:2]
    assert np.linalg.norm(moved - 0.8 * np.array([math.cos(before[2]), math.sin(before[2])])) < 0.15
    with pytest.raises(ValueError, match="finite"):
        r.base.set_pose(math.nan, 0.0, 0.0)


def test_readings_keep_the_interface_promises(rig):
    """What twin.hal.conformance checks of a base: readings stamped within the call, drives
    of zero length (with and without a heading) reached, set_pose(odometry) a no-op."""
    r = rig()
    for goal_yaw in (None, "current"):
        before = r.clock.now()
        odo = r.base.odometry()
        assert before <= odo.timestamp <= r.clock.now()
        yaw = None if goal_yaw is None else odo.yaw
        result = r.base.drive_to([odo.x, odo.y], yaw)
        after = r.clock.now()
        assert result.status is DriveStatus.REACHED
        assert before <= result.timestamp <= after
        assert before <= result.odometry.timestamp <= after
        assert result.duration < 5.0
    now = r.base.odometry()
    r.base.set_pose(now.x, now.y, now.yaw)
    after = r.base.odometry()
    assert math.hypot(after.x - now.x, after.y - now.y) <= 1e-6
    # A goal that is not finite is a reading, not an error.
    result = r.base.drive_to([math.nan, 0.0])
    assert result.status is DriveStatus.BLOCKED
    assert "finite" in result.message


def test_leds_switch_and_the_world_sees_them(rig):
    world_leds = RecordingLeds()
    r = rig(leds=world_leds, led_bits=(4, 5, 6, 7))
    leds = ArcosLeds(r.conn, child="child1", bits=(4, 5, 6, 7))
    try:
        switched = leds.switch([True, False, True, False])
        assert switched.on == (True, False, True, False)
        assert switched.child == "child1"
        assert world_leds.seen[-1] == (True, False, True, False)
        assert r.conn.latest().digout & 0xF0 == 0b0101_0000
        leds.switch([False, True, False, False])
        assert world_leds.seen[-1] == (False, True, False, False)
        with pytest.raises(ValueError, match="4 flags"):
            leds.switch([True])
    finally:
        leds.close()
    with pytest.raises(ValueError, match="bits"):
        ArcosLeds(r.conn, child="child1", bits=(1, 1))


def test_a_goal_inside_an_obstacle_ends_stalled(rig):
    r = rig(robot="child2")  # (1.5, -1.5); the pillar stands at (6.5, -2.2), 0.6 m square
    result = r.base.drive_to([6.5, -2.2])
    assert result.status is DriveStatus.BLOCKED
    assert result.message == "stalled"
    truth = r.truth()
    pillar = r.frame.pose([6.5, -2.2, 0.0])[:2]
    assert 0.3 < np.linalg.norm(truth[:2] - pillar) < 1.5
    assert not r.body.moving
    assert r.conn.latest().left_vel == 0 == r.conn.latest().right_vel


def test_an_unreachable_point_ends_stalled(rig):
    r = rig(unreachable=[(3.0, 1.5)])
    result = r.base.drive_to([3.0, 1.5])
    assert result.status is DriveStatus.BLOCKED
    assert result.message == "stalled"
    assert np.linalg.norm(r.truth()[:2] - [3.0, 1.5]) > 0.4


def test_e_stop_and_timeout_stop_the_robot(rig):
    r = rig(drive_timeout_s=1.5)
    result = r.base.drive_to(r.truth()[:2] + np.array([3.0, 0.0]))
    assert result.status is DriveStatus.TIMEOUT
    assert "not at the goal after" in result.message
    assert not r.body.moving
    r.base.drive_timeout_s = 60.0
    r.faults.estop = True
    result = r.base.drive_to(r.truth()[:2] + np.array([-1.0, 0.0]))
    assert result.status is DriveStatus.BLOCKED
    assert result.message == "e-stop"
    assert not r.body.moving


def test_motors_switched_off_end_a_drive_blocked(rig):
    r = rig()
    r.conn.send(Command.ENABLE, 0)
    r.conn.wait_for(lambda s: not s.motors_enabled)
    result = r.base.drive_to(r.truth()[:2] + np.array([1.0, 0.0]))
    assert result.status is DriveStatus.BLOCKED
    assert result.message == "motors disabled"
    assert not r.body.moving


def test_a_drive_that_fails_on_the_host_stops_the_robot(rig, monkeypatch):
    """The keep-alive would keep a robot driving at its last command: a control loop that
    raises must stop it before the error goes on."""
    r = rig()
    control = r.base._control
    calls = []

    def failing(*args):
        calls.append(args)
        if len(calls) > 5:
            raise RuntimeError("controller bug")
        return control(*args)

    monkeypatch.setattr(r.base, "_control", failing)
    with pytest.raises(RuntimeError, match="controller bug"):
        r.base.drive_to(r.truth()[:2] + np.array([2.0, 0.0]))
    r.conn.wait_for(lambda s: not s.moving, 5.0)
    sent = [c for c in r.emulator.commands if c[0] in (Command.VEL, Command.RVEL)]
    assert sent[-2:] == [(Command.VEL, 0), (Command.RVEL, 0)]
    assert r.emulator.watchdog_trips == 0  # stopped by command, not by the watchdog


def test_a_noisy_line_does_not_break_the_session(rig):
    r = rig()
    r.faults.garbage = b"\x01\x02\xfa\x99junk"
    r.faults.corrupt_sips = 3
    r.conn.wait_for(lambda s: True)
    r.conn.write_raw(b"\xfa\xfb\x06\x0b\x3b")  # a VEL cut short
    r.conn.write_raw(b"\xfa\xfb\x06\x0b\x3b\xf4\x01\x00\x00")  # VEL 500, wrong checksum
    r.conn.write_raw(b"noise")
    r.faults.truncate_sips = 2
    for _ in range(8):
        r.conn.wait_for(lambda s: True)
    assert not r.body.moving  # neither bad VEL moved it
    result = r.base.drive_to(r.truth()[:2] + np.array([0.5, 0.0]))
    assert result.reached
    rejected = r.conn.rejected
    assert rejected["garbage_bytes"] > 0
    assert rejected["bad_checksum"] + rejected["truncated"] >= 5
    assert r.emulator.reader.garbage > 0
    assert r.emulator.reader.bad_checksum + r.emulator.reader.truncated >= 2


def test_a_silent_robot_is_lost(rig):
    r = rig(timeout_s=1.0)
    r.faults.silent = True
    with pytest.raises(DeviceLostError) as lost:
        r.base.drive_to(r.truth()[:2] + np.array([1.0, 0.0]))
    assert lost.value.device == "child1"
    time.sleep(r.clock.wall(1.2))
    with pytest.raises(DeviceLostError, match="no SIP"):
        r.base.odometry()


@pytest.mark.parametrize("link", ["tcp", "pty"])
def test_a_dropped_link_is_lost(rig, link):
    r = rig(link)
    r.faults.drop_link = True
    deadline = time.monotonic() + 5.0
    while not r.conn.lost and time.monotonic() < deadline:
        time.sleep(0.01)
    with pytest.raises(DeviceLostError, match="child1") as lost:
        r.base.odometry()
    assert str(lost.value).startswith(f"child1 on {r.conn.port} (ARCOS): connection lost")
    with pytest.raises(DeviceLostError):
        r.base.drive_to([0.0, 0.0])
    r.base.close()
    r.base.close()


def test_close_twice_and_nothing_after(rig):
    r = rig()
    r.base.close()
    r.base.close()
    assert r.emulator.commands[-1][0] == 2  # CLOSE
    with pytest.raises(DeviceLostError, match="closed"):
        r.base.odometry()


def test_nobody_answering_or_the_wrong_model(rig):
    clock = WallClock(SCALE)
    link = TcpLink()  # listens, never answers
    try:
        with pytest.raises(DeviceLostError, match="synchronised"):
            PioneerConnection(link.address, model="p3dx", clock=clock, timeout_s=1.0)
    finally:
        link.close()
    with pytest.raises(DeviceLostError, match="cannot open"):
        PioneerConnection("/nonexistent/tty", model="p3dx", clock=clock)
    r = rig("tcp", connect=False)
    with pytest.raises(ValueError, match="p3at"):
        PioneerConnection(r.emulator.address, model="p3at", clock=r.clock)
    for pulse_s in (0.0, 1.5, math.nan):  # a PULSE at least twice per 2 s watchdog
        with pytest.raises(ValueError, match="pulse_s"):
            PioneerConnection(r.emulator.address, model="p3dx", clock=r.clock, pulse_s=pulse_s)


def test_a_session_left_open_is_closed_and_opened_again(rig):
    r = rig("tcp", connect=False)
    port = int(r.emulator.address.rsplit(":", 1)[1])
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as s:
        for number in (0, 1, 2, 1):  # SYNC0, SYNC1, SYNC2, OPEN; then hang up
            s.sendall(command(number))
            time.sleep(0.02)
    deadline = time.monotonic() + 2.0
    while not r.emulator.session_open and time.monotonic() < deadline:
        time.sleep(0.01)
    assert r.emulator.session_open
    conn = PioneerConnection(r.emulator.address, model="p3dx", clock=r.clock, name="child1")
    try:
        assert conn.identify()["name"] == "child1"
        assert Command.CLOSE in [n for n, _ in r.emulator.commands]
    finally:
        conn.close()


def test_an_h8_controller_is_refused_for_its_other_distance_units(rig):
    # A bare subtype is the older H8 controller: its positions come in 0.485 mm units, which
    # read as millimetres would put the robot twice as far as it went.
    r = rig("pty", connect=False)
    r.emulator.params = dataclasses.replace(r.emulator.params, subtype="p3dx")
    with pytest.raises(ValueError, match="H8 controller"):
        PioneerConnection(r.emulator.address, model="p3dx", clock=r.clock)
