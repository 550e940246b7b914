"""ARCOS framing, commands and SIPs: packets written by hand from the manual, round trips of
any command, every single-byte corruption detected, a noisy stream cut into its packets."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.drivers.arcos.platforms import PLATFORMS, platform
from twin.drivers.arcos.protocol import (
    SYNC0,
    SYNC1,
    SYNC2,
    ArgType,
    Command,
    PacketReader,
    ProtocolError,
    checksum,
    command,
    frame,
    parse_command,
    parse_sync2_reply,
    sync2_reply,
    unframe,
)
from twin.drivers.arcos.sip import Sip, decode_sip, encode_sip, unroll_position

# -- packets by hand ---------------------------------------------------------------------------
# The first three and ENABLE 1 are printed in the Pioneer 3 Operations Manual (ARCOS chapter,
# "The Client-Server Connection": "SYNC0: 250, 251, 3, 0, 0, 0" and so on; ENABLE 1 as
# "0xFA, 0xFB, 0x06, 0x04, 0x3B, 0x01, 0x00, 0x05, 0x3B"); the others follow its rules:
# words of successive payload bytes, high byte first, summed modulo 2**16, an odd last byte
# XORed into the low byte, the checksum sent high byte first.


@pytest.mark.parametrize(
    ("number", "argument", "packet"),
    [
        (SYNC0, None, "fa fb 03 00 00 00"),
        (SYNC1, None, "fa fb 03 01 00 01"),
        (SYNC2, None, "fa fb 03 02 00 02"),
        (Command.PULSE, None, "fa fb 03 00 00 00"),
        (Command.OPEN, None, "fa fb 03 01 00 01"),
        (Command.CLOSE, None, "fa fb 03 02 00 02"),
        # ENABLE 1: words 0x043B + 0x0100 = 0x053B.
        (Command.ENABLE, 1, "fa fb 06 04 3b 01 00 05 3b"),
        # VEL -200: NINT with |200| = 0xC8, words 0x0B1B + 0xC800 = 0xD31B.
        (Command.VEL, -200, "fa fb 06 0b 1b c8 00 d3 1b"),
        # RVEL 10: words 0x153B + 0x0A00 = 0x1F3B.
        (Command.RVEL, 10, "fa fb 06 15 3b 0a 00 1f 3b"),
        # DIGOUT mask 0x0F (bits 8-15), outputs 0x05 (bits 0-7): argument 0x0F05,
        # words 0x1E3B + 0x050F = 0x234A.
        (Command.DIGOUT, 0x0F05, "fa fb 06 1e 3b 05 0f 23 4a"),
        # SETA -300 (a deceleration): NINT |300| = 0x012C, words 0x051B + 0x2C01 = 0x311C.
        (Command.SETA, -300, "fa fb 06 05 1b 2c 01 31 1c"),
        # VEL2 left +10, right -10 (x 20 mm/s): bits 8-15 left 0x0A, bits 0-7 right 0xF6,
        # argument 0x0AF6, words 0x203B + 0xF60A = 0x1645 (modulo 2**16).
        (Command.VEL2, 0x0AF6, "fa fb 06 20 3b f6 0a 16 45"),
        # STOP: 0x001D.
        (Command.STOP, None, "fa fb 03 1d 00 1d"),
        # E_STOP: one byte, XORed into the low byte: 0x0037.
        (Command.E_STOP, None, "fa fb 03 37 00 37"),
        # A string "ab": words 0x0F2B + 0x0261 = 0x118C, last byte 0x62 XORed: 0x11EE.
        (15, "ab", "fa fb 07 0f 2b 02 61 62 11 ee"),
    ],
)
def test_commands_match_the_manual(number, argument, packet):
    assert command(number, argument) == bytes.fromhex(packet)
    expected = argument.encode() if isinstance(argument, str) else argument
    assert parse_command(unframe(bytes.fromhex(packet))) == (number, expected)


def test_command_numbers_are_the_manuals():
    assert (Command.PULSE, Command.OPEN, Command.CLOSE, Command.ENABLE) == (0, 1, 2, 4)
    assert (Command.SETA, Command.SETV, Command.SETRV, Command.VEL) == (5, 6, 10, 11)
    assert (Command.RVEL, Command.STOP, Command.DIGOUT, Command.VEL2) == (21, 29, 30, 32)
    assert Command.E_STOP == 55
    assert (SYNC0, SYNC1, SYNC2) == (0, 1, 2)


def test_a_sip_written_by_hand_decodes():
    """A standard SIP laid out field by field as the manual's table has it."""
    payload = bytes.fromhex(
        "33"  # type: robot moving
        "e8 83"  # XPOS 0x83E8: 15 bits kept, 0x03E8 = 1000
        "d0 07"  # YPOS 2000
        "00 fc"  # THPOS -1024 (a quarter turn clockwise)
        "2c 01"  # L VEL 300
        "d4 fe"  # R VEL -300
        "79"  # BATTERY 12.1 V
        "01 01"  # STALL AND BUMPERS: left (bit 0) and right (bit 8) stalled
        "00 fc"  # CONTROL -1024
        "21 00"  # FLAGS: motors enabled (bit 0), STOP button (bit 5)
        "2d"  # COMPASS 90 degrees
        "02 03 f4 01 04 e8 03"  # 2 sonar readings: #3 500 mm, #4 1000 mm
        "00 01 80 0f 5a"  # GRIP_STATE, ANPORT, ANALOG, DIGIN, DIGOUT
        "7a 00"  # BATTERYX10 12.2 V
        "00"  # CHARGESTATE
        "f0 fd"  # ROTVEL -528: -52.8 deg/s
        "00 00"  # FAULTFLAGS
    )
    sip = decode_sip(unframe(frame(payload)))
    assert sip.moving
    assert (sip.xpos, sip.ypos, sip.thpos) == (1000, 2000, -1024)
    assert (sip.left_vel, sip.right_vel, sip.battery) == (300, -300, 121)
    assert (sip.stalled, sip.estop, sip.motors_enabled) == (True, True, True)
    assert sip.compass == 45
    assert sip.sonars == ((3, 500), (4, 1000))
    assert (sip.anport, sip.analog, sip.digin, sip.digout) == (1, 128, 15, 0x5A)
    assert (sip.battery_x10, sip.charge_state, sip.rotvel, sip.fault_flags) == (122, 0, -528, 0)
    assert sip.battery_volts == pytest.approx(12.2)
    dx = PLATFORMS["p3dx"]
    assert dx.heading_rad(sip.thpos) == pytest.approx(-math.pi / 2)


def test_checksum_of_odd_and_even_payloads():
    assert checksum(b"") == 0
    assert checksum(b"\x01") == 0x0001
    assert checksum(b"\x12\x34\x56\x78") == (0x1234 + 0x5678) & 0xFFFF
    assert checksum(b"\xff\xff\xff\xff") == 0xFFFE  # carries beyond 16 bits are dropped
    assert checksum(b"\x12\x34\x56") == 0x1234 ^ 0x56


def test_bad_arguments_are_refused_with_the_value_named():
    with pytest.raises(ProtocolError, match="70000"):
        command(Command.VEL, 70000)
    with pytest.raises(ProtocolError, match="300"):
        command(300)
    with pytest.raises(ProtocolError, match="argument type"):
        parse_command(bytes([11, 0x4B, 0, 0]))
    with pytest.raises(ProtocolError, match="checksum"):
        unframe(bytes.fromhex("fa fb 03 00 00 01"))


# -- properties ----------------------------------------------------------------------------------

numbers = st.integers(0, 255)
arguments = st.one_of(
    st.none(),
    st.integers(-32767, 65535),
    st.binary(min_size=0, max_size=195),
)


@given(numbers, arguments)
def test_any_command_round_trips(number, argument):
    packet = command(number, argument)
    assert packet[:2] == b"\xfa\xfb"
    assert packet[2] == len(packet) - 3
    assert parse_command(unframe(packet)) == (number, argument)


@given(numbers, arguments, st.data())
def test_any_single_byte_corruption_is_detected(number, argument, data):
    packet = bytearray(command(number, argument))
    at = data.draw(st.integers(0, len(packet) - 1), label="position")
    flip = data.draw(st.integers(1, 255), label="xor")
    packet[at] ^= flip
    with pytest.raises(ProtocolError):
        unframe(bytes(packet))
    # A reader drops it too and finds the good packets that follow (enough of them to
    # complete whatever length a corrupted count announced).
    reader = PacketReader()
    got = list(reader.feed(bytes(packet) + command(Command.PULSE) * 40))
    assert got[-1] == bytes([Command.PULSE])
    assert reader.garbage + reader.bad_checksum + reader.truncated > 0


@given(st.lists(st.tuples(numbers, arguments), min_size=1, max_size=8), st.binary(max_size=40))
def test_a_noisy_stream_yields_its_packets(commands, noise):
    noise = noise.replace(b"\xfa", b"\x00")  # noise without a header's first byte
    stream = b"".join(noise + command(n, a) for n, a in commands)
    reader = PacketReader()
    payloads = []
    for k in range(0, len(stream), 7):  # as a serial line delivers it: in pieces
        payloads += reader.feed(stream[k : k + 7])
    assert [parse_command(p) for p in payloads] == commands
    assert reader.garbage == len(noise) * len(commands)


def test_bad_and_cut_packets_are_counted_and_skipped():
    good = command(Command.VEL, 100)
    bad = bytearray(command(Command.VEL, 300))
    bad[-1] ^= 0xFF
    cut = command(Command.RVEL, 20)[:5]
    reader = PacketReader()
    got = list(reader.feed(b"\x01\x02" + bytes(bad) + cut + good + b"\xfa\xfb\xff" + good))
    assert [parse_command(p) for p in got] == [(Command.VEL, 100)] * 2
    assert reader.bad_checksum == 1
    assert reader.truncated == 1
    assert reader.garbage >= 2
    assert reader.rejected["truncated"] == 1


# -- SYNC2, SIPs, platforms -------------------------------------------------------------


def test_sync2_answer_carries_name_type_subtype():
    packet = sync2_reply("child1", "Pioneer", "p3dx")
    assert packet[3] == SYNC2
    assert parse_sync2_reply(unframe(packet)) == ("child1", "Pioneer", "p3dx")


sips = st.builds(
    Sip,
    timestamp=st.just(0.0),
    moving=st.booleans(),
    xpos=st.integers(0, 0x7FFF),
    ypos=st.integers(0, 0x7FFF),
    thpos=st.integers(-2048, 2047),
    left_vel=st.integers(-32768, 32767),
    right_vel=st.integers(-32768, 32767),
    battery=st.integers(0, 255),
    stall_bumpers=st.integers(0, 0xFFFF),
    control=st.integers(-2048, 2047),
    flags=st.integers(0, 0xFFFF),
    compass=st.integers(0, 255),
    sonars=st.lists(st.tuples(st.integers(0, 31), st.integers(0, 5000)), max_size=8).map(tuple),
    digin=st.integers(0, 255),
    digout=st.integers(0, 255),
    battery_x10=st.one_of(st.none(), st.integers(0, 0xFFFF)),
)


@given(sips)
def test_any_sip_round_trips(sip):
    back = decode_sip(unframe(encode_sip(sip)))
    expected = sip
    if sip.battery_x10 is not None:  # the extended fields come as a block
        expected = Sip(**{**sip.__dict__, "charge_state": 0, "rotvel": 0, "fault_flags": 0})
    assert back == expected
    assert back.stalled == bool(sip.stall_bumpers & 0x0101)


def test_sip_flags():
    sip = Sip(0.0, True, 0, 0, 0, 0, 0, 121, 0x0100, 0, 0x0021, battery_x10=None)
    assert sip.stalled
    assert sip.estop
    assert sip.motors_enabled
    bumpers_only = Sip(0.0, False, 0, 0, 0, 0, 0, 121, 0xFEFE, 0, 0x0040)
    assert not bumpers_only.stalled  # bits 1-7 and 9-15 are bumpers, not stalls
    assert not bumpers_only.estop  # bit 6 is E_STALL, not the STOP button
    assert not bumpers_only.motors_enabled
    assert sip.battery_volts == pytest.approx(12.1)
    with pytest.raises(ProtocolError, match="not a standard SIP"):
        decode_sip(bytes([0x90, 0, 0]))
    with pytest.raises(ProtocolError, match="too short"):
        decode_sip(bytes([0x32, 1, 2, 3]))


def test_platform_conversion_factors():
    """ARIA's p3dx-sh.p / p3at-sh.p: DistConvFactor 1, VelConvFactor 1, AngleConvFactor
    2 pi / 4096 (0.001534 rounded), DiffConvFactor 0.0056 / 0.0034, Vel2Divisor 20."""
    dx, at = PLATFORMS["p3dx"], PLATFORMS["p3at"]
    for p in (dx, at):
        assert (p.dist_conv, p.vel_conv, p.vel2_divisor) == (1.0, 1.0, 20.0)
        assert p.angle_conv == pytest.approx(0.001534, abs=5e-7)
        assert p.heading_units(math.pi / 2) == 1024  # 4096 units per turn
        assert p.heading_rad(2048) == pytest.approx(math.pi)
        for a in (-3.1, -0.5, 0.0, 0.001, 1.2, 3.1):
            assert p.heading_rad(p.heading_units(a)) == pytest.approx(a, abs=p.angle_conv)
        assert p.position_m(p.position_units(12.3456)) == pytest.approx(12.346)
        assert p.wheel_units(-0.4567) == -457
    assert dx.diff_conv == 0.0056
    assert at.diff_conv == 0.0034
    assert 4096 * dx.angle_conv == pytest.approx(2 * math.pi, rel=1e-12)
    assert platform("P3AT") is at
    with pytest.raises(ValueError, match="p3xx"):
        platform("p3xx")


@given(st.integers(-200_000, 200_000), st.lists(st.integers(-3000, 3000), max_size=30))
def test_positions_unroll_across_the_15_bit_roll_over(start, steps):
    truth = start
    continuous = unroll_position(None, truth & 0x7FFF)
    offset = truth - continuous  # the first SIP fixes the origin
    for step in steps:
        truth += step
        continuous = unroll_position(continuous, truth & 0x7FFF)
        assert continuous + offset == truth


def test_frame_limits():
    with pytest.raises(ProtocolError):
        frame(b"")
    with pytest.raises(ProtocolError):
        frame(bytes(199))
    assert len(frame(bytes(198))) == 203
    assert ArgType.STR == 0x2B
    assert ArgType.INT == 0x3B
    assert ArgType.NINT == 0x1B
