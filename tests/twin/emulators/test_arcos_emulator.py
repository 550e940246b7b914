"""The emulated Pioneer speaks ARCOS as the manual has it: a raw client over TCP writes the
packets byte for byte and reads what the robot answers. And the body it drives: a
unicycle with acceleration limits, stalls at walls, obstacles and unreachable points, a
stopping error at each stop."""

from __future__ import annotations

import math
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.drivers.arcos.protocol import Command, PacketReader, command, parse_sync2_reply
from twin.drivers.arcos.sip import Sip, decode_sip, is_sip
from twin.drivers.clock import WallClock
from twin.emulators.arcos import ArcosFaults, PioneerEmulator
from twin.emulators.links import TcpLink
from twin.emulators.pioneer_body import PioneerBody
from twin.scenario import load_scenario
from twin.scenario.schema import StoppingConfig
from twin.sim.rig.frames import WorldFrame
from twin.sim.world import build_world

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"
SCALE = 20.0


def _world():
    sc = load_scenario(SMOKE)
    world = build_world(sc)
    world.run(0.5)
    position, rotation = world.instrument_pose(sc.robots.parent.name)
    return world, WorldFrame.from_instrument(position, rotation)


def _body(robot: str = "child1", stopping=None, unreachable=()) -> PioneerBody:
    world, frame = _world()
    return PioneerBody(
        world,
        robot,
        frame,
        threading.RLock(),
        stopping=world.scenario.noise.stopping if stopping is None else stopping,
        rng=np.random.default_rng(3),
        unreachable=unreachable,
    )


class Client:
    """A bare ARCOS client on a socket: bytes out, packets in."""

    def __init__(self, port: int, clock: WallClock) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.clock = clock
        self.reader = PacketReader()
        self.pending: list[bytes] = []

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def packet(self, wall_timeout: float = 2.0) -> bytes:
        deadline = time.monotonic() + wall_timeout
        while not self.pending:
            self.sock.settimeout(max(deadline - time.monotonic(), 1e-3))
            try:
                data = self.sock.recv(4096)
            except TimeoutError:
                data = b""
            if not data and time.monotonic() >= deadline:
                raise AssertionError("the robot sent nothing")
            self.pending += self.reader.feed(data)
        return self.pending.pop(0)

    def sip(self) -> Sip:
        while True:
            p = self.packet()
            if is_sip(p):
                return decode_sip(p, self.clock.now())

    def sips_for(self, rig_seconds: float) -> list[Sip]:
        out: list[Sip] = []
        end = self.clock.now() + rig_seconds
        while self.clock.now() < end:
            out.append(self.sip())
        return out

    def until(self, predicate, rig_seconds: float) -> Sip:
        """The first SIP that satisfies ``predicate``, within ``rig_seconds``."""
        end = self.clock.now() + rig_seconds
        while self.clock.now() < end:
            sip = self.sip()
            if predicate(sip):
                return sip
        raise AssertionError(f"no such SIP in {rig_seconds} s")

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def robot():
    """An emulated P3-DX on TCP and a client that has opened a session."""
    opened: list = []

    def make(faults: ArcosFaults | None = None, watchdog_s: float = 2.0):
        body = _body()
        clock = WallClock(SCALE)
        link = TcpLink()
        emulator = PioneerEmulator(
            body, model="p3dx", time=clock, link=link, faults=faults, watchdog_s=watchdog_s
        )
        opened.append(emulator)
        emulator.start()
        client = Client(link.port, clock)
        opened.append(client)
        # The handshake, byte for byte as the manual writes it.
        for sync in ("fa fb 03 00 00 00", "fa fb 03 01 00 01"):
            client.send(bytes.fromhex(sync))
            assert client.packet() == bytes.fromhex(sync)[3:4]
        client.send(bytes.fromhex("fa fb 03 02 00 02"))
        assert parse_sync2_reply(client.packet()) == ("child1", "Pioneer", "p3dx-sh")
        client.send(bytes.fromhex("fa fb 03 01 00 01"))  # OPEN
        return emulator, client, body, clock

    try:
        yield make
    finally:
        for thing in reversed(opened):
            thing.close()
    for thing in opened:
        assert getattr(thing, "error", None) is None  # no emulator thread died


def test_open_starts_the_sip_stream_and_enable_vel_move_the_robot(robot):
    _emulator, client, body, clock = robot()
    sips = client.sips_for(1.0)
    assert 3 <= len(sips) <= 12  # every 0.1 s (fewer when the machine is busy)
    assert sips[-1].xpos == 0
    assert not sips[-1].motors_enabled
    assert not sips[-1].moving
    client.send(command(Command.VEL, 300))  # ignored: the motors are disabled
    client.sips_for(0.5)
    assert not body.moving
    start = clock.now()
    client.send(command(Command.ENABLE, 1) + command(Command.VEL, 300))
    for _ in range(10):
        client.send(command(Command.PULSE))
        sips = client.sips_for(0.2)
    last = sips[-1]
    assert last.moving
    assert last.motors_enabled
    assert last.left_vel == pytest.approx(300, abs=2)
    assert last.right_vel == pytest.approx(300, abs=2)
    # About 0.3 m/s since the command (less the ramp), straight ahead.
    assert 300 < last.xpos <= 300 * (clock.now() - start) + 5
    assert abs(last.ypos) < 5
    client.send(command(Command.E_STOP))
    sip = client.sips_for(0.3)[-1]
    assert not sip.moving
    assert sip.left_vel == 0


def test_the_watchdog_stops_a_robot_that_hears_nothing(robot):
    emulator, client, _body, clock = robot(watchdog_s=1.0)
    sent = clock.now()
    client.send(command(Command.ENABLE, 1) + command(Command.VEL, 400) + command(Command.RVEL, -10))
    client.until(lambda s: s.moving, 5.0)
    stopped = client.until(lambda s: not s.moving, 10.0)
    assert clock.now() - sent > 1.0  # not before the watchdog's time
    assert stopped.left_vel == 0 == stopped.right_vel
    assert emulator.watchdog_trips == 1
    stopped_at = stopped.xpos
    assert stopped_at > 0
    # The session goes on: the next packet, a PULSE even, revives it, and it accelerates
    # again to the speeds it was last told (the manual's watchdog).
    client.send(command(Command.PULSE))
    revived = client.until(lambda s: s.moving, 5.0)
    assert revived.right_vel < revived.left_vel  # RVEL -10 still holds: turning clockwise
    assert client.sips_for(0.6)[-1].xpos > stopped_at
    client.send(command(Command.VEL, 0) + command(Command.RVEL, 0))
    assert not client.until(lambda s: not s.moving, 5.0).moving


def test_bad_packets_are_dropped_and_the_session_goes_on(robot):
    emulator, client, _body, _clock = robot()
    bad = bytearray(command(Command.ENABLE, 1))
    bad[-1] ^= 0x01  # wrong checksum
    cut = command(Command.ENABLE, 1)[:6]  # cut short
    client.send(b"\x00\x13garbage" + bytes(bad) + cut + b"\xfa\xfb\xfe")
    sips = client.sips_for(0.5)
    assert len(sips) >= 3
    assert not sips[-1].motors_enabled
    client.send(command(Command.ENABLE, 1))
    assert client.sips_for(0.3)[-1].motors_enabled
    r = emulator.reader
    assert r.garbage >= 9
    assert r.bad_checksum + r.truncated >= 2


def test_digout_changes_only_the_selected_bits(robot):
    emulator, client, _body, _clock = robot()
    client.send(command(Command.DIGOUT, 0xFF_0F))
    assert client.sips_for(0.3)[-1].digout == 0x0F
    client.send(command(Command.DIGOUT, 0x03_00))  # clear bits 0 and 1 only
    assert client.sips_for(0.3)[-1].digout == 0x0C
    assert emulator.digout == 0x0C


def test_faults_show_in_the_sips(robot):
    faults = ArcosFaults()
    _emulator, client, body, clock = robot(faults)
    client.send(command(Command.ENABLE, 1) + command(Command.VEL, 300))
    faults.stall = True
    sip = client.sips_for(0.5)[-1]
    assert sip.stalled
    assert not body.moving
    faults.stall = False
    faults.estop = True
    sip = client.sips_for(0.3)[-1]
    assert sip.estop
    assert not sip.stalled
    faults.estop = False
    faults.corrupt_sips = 3
    r = client.reader
    client.until(lambda s: r.bad_checksum + r.truncated >= 3 and faults.corrupt_sips == 0, 10.0)
    client.sips_for(0.5)
    assert r.bad_checksum + r.truncated == 3  # dropped; the good ones around them came through
    faults.silent = True
    time.sleep(clock.wall(0.5))
    client.pending.clear()
    with pytest.raises(AssertionError, match="nothing"):
        client.packet(wall_timeout=clock.wall(0.5))


def test_close_ends_the_session_and_a_new_one_can_start(robot):
    emulator, client, _body, clock = robot()
    client.sips_for(0.3)
    client.send(command(Command.CLOSE))
    time.sleep(clock.wall(0.3))
    assert not emulator.session_open
    client.pending.clear()
    with pytest.raises(AssertionError):
        client.packet(wall_timeout=clock.wall(0.5))
    client.send(command(0))
    assert client.packet() == b"\x00"


# -- the body ------------------------------------------------------------------------------------


def test_body_follows_a_unicycle_with_its_limits():
    body = _body(stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=0.0))
    start = body.truth.copy()
    p = body.platform
    body.advance(5.0, 0.0, 0.1)  # far beyond the platform's speed
    assert body.v == pytest.approx(p.max_accel * 0.1)
    for _ in range(40):
        body.advance(5.0, 0.0, 0.1)
    assert body.v == pytest.approx(p.max_speed)
    for _ in range(40):
        body.advance(0.0, 0.0, 0.1)
    assert not body.moving
    travelled = body.truth[:2] - start[:2]
    assert np.linalg.norm(travelled) == pytest.approx(np.linalg.norm(body.odometry[:2]))
    assert travelled[0] > 2.0
    assert abs(travelled[1]) < 1e-6
    # The world shows it where the body says.
    np.testing.assert_allclose(body.world.robot_pose("child1")[:2], body.truth[:2], atol=2e-3)
    # A quarter turn on the spot.
    for _ in range(200):
        body.advance(0.0, 0.5, 0.01)
    assert body.w == pytest.approx(0.5)


def _drive_and_stop(body: PioneerBody) -> np.ndarray:
    """Drive 0.3 m/s for 1 s, stop; the truth's offset from start (x) odometry, (2,) m."""
    origin = body.truth[:2].copy()
    for _ in range(10):
        body.advance(0.3, 0.0, 0.1)
    for _ in range(10):
        body.advance(0.0, 0.0, 0.1)
    assert not body.moving
    # It started heading along +x in both frames (yaw ~ 0), odometry from zero.
    return body.truth[:2] - origin - body.odometry[:2]


def test_body_stops_with_the_stopping_error():
    stopping = StoppingConfig(sigma_xy=0.05, sigma_yaw=0.02)
    exact = _drive_and_stop(_body(stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=0.0)))
    assert np.linalg.norm(exact) < 1e-3  # without the error, truth and odometry agree
    errors = [_drive_and_stop(_body(stopping=stopping)) for _ in range(2)]
    np.testing.assert_array_equal(errors[0], errors[1])  # one seed, one draw
    assert 1e-4 < np.linalg.norm(errors[0]) < 5 * stopping.sigma_xy * math.sqrt(2)


@pytest.mark.parametrize(
    ("robot", "v", "unreachable"),
    [
        ("child1", 1.0, ()),  # turned north: the wall at y = 3
        ("child2", 1.0, ()),  # east from (1.5, -1.5): the east wall (the pillar is south of it)
        ("child1", 1.0, [(3.0, 1.5)]),  # east: the unreachable point
    ],
)
def test_body_stalls_instead_of_entering(robot, v, unreachable):
    body = _body(
        robot, stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=0.0), unreachable=unreachable
    )
    if robot == "child1" and not unreachable:
        for _ in range(200):  # turn to face north
            body.advance(0.0, 1.0, 0.01)
            if abs(body.truth[2] - math.pi / 2) < 0.02:
                break
        body.advance(0.0, 0.0, 1.0)
    stalled = False
    for _ in range(400):
        body.advance(v, 0.0, 0.05)
        if body.stalled:
            stalled = True
            break
    space = body.world.scenario.space
    if robot == "child2":
        # Heading east it meets the east wall (x = 8) first.
        assert stalled
        assert body.truth[0] <= space.x_range[1] - body.radius + 1e-9
    elif unreachable:
        assert stalled
        target = body.frame.points_to_mujoco([3.0, 1.5, 0.0])[:2]
        assert np.linalg.norm(body.truth[:2] - target) > 0.5
    else:
        assert stalled
        assert body.truth[1] <= space.y_range[1] - body.radius + 1e-9
    assert not body.moving
    body.advance(0.0, 0.0, 0.1)
    assert not body.stalled
