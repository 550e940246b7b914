"""Records to JSON values and back: round trips, strict JSON, errors that name the field."""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.hal.readings import (
    DriveResult,
    DriveStatus,
    Event,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)
from twin.record import decode, encode


def through_json(record: object) -> object:
    """encode -> strict JSON text -> decode."""
    text = json.dumps(encode(record), allow_nan=False)
    return decode(json.loads(text))


def assert_same_record(a: object, b: object) -> None:
    """Field by field; arrays compared with NaN equal to NaN."""
    assert type(a) is type(b)
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert isinstance(y, np.ndarray), f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        elif hasattr(x, "__dataclass_fields__"):
            assert_same_record(x, y)
        else:
            assert x == y, f.name
            assert type(x) is type(y) or {type(x), type(y)} <= {int, float}, f.name


finite = st.floats(allow_nan=False, allow_infinity=False)
angle = st.floats(-1.0, 1.0, allow_nan=False)
name = st.text(min_size=1, max_size=8)
tilts = st.builds(TiltReading, timestamp=finite, roll=angle, pitch=angle)


@settings(max_examples=50, deadline=None)
@given(st.builds(OdometryReading, robot=name, timestamp=finite, x=finite, y=finite, yaw=finite))
def test_odometry_round_trip(reading: OdometryReading) -> None:
    back = through_json(reading)
    assert back == reading
    assert_same_record(reading, back)


@settings(max_examples=50, deadline=None)
@given(tilts)
def test_tilt_round_trip(reading: TiltReading) -> None:
    assert through_json(reading) == reading


@settings(max_examples=50, deadline=None)
@given(
    st.builds(
        TotalStationMeasurement,
        timestamp=finite,
        distance=st.floats(1e-6, 1e4),
        horizontal=st.floats(0.0, 2 * math.pi, exclude_max=True),
        zenith=st.floats(0.0, math.pi),
        tilt=st.none() | tilts,
    )
)
def test_total_station_round_trip(shot: TotalStationMeasurement) -> None:
    back = through_json(shot)
    assert back == shot
    assert_same_record(shot, back)


@pytest.mark.parametrize("status", list(DriveStatus))
@pytest.mark.parametrize("goal_yaw", [0.25, math.nan])
def test_drive_result_round_trip(status: DriveStatus, goal_yaw: float) -> None:
    result = DriveResult(
        robot="child_1",
        timestamp=12.5,
        goal=[1.0, -2.0, goal_yaw],
        status=status,
        odometry=OdometryReading("child_1", 12.5, 0.99, -2.01, 0.24),
        duration=7.25,
        message="ok",
    )
    encoded = encode(result)
    assert encoded["status"] == status.value
    assert encoded["odometry"]["_type"] == "OdometryReading"
    back = through_json(result)
    assert isinstance(back, DriveResult)
    assert back.status is status
    assert_same_record(result, back)


def test_led_switch_round_trip() -> None:
    switch = LedSwitch("child_2", 3.0, (True, False, True))
    back = through_json(switch)
    assert back == switch
    assert isinstance(back.on, tuple)


def test_event_round_trip() -> None:
    event = Event(4.5, "lost_lock", "prism lost", {"aim_level": [1.0, 2.0, 0.5], "tries": 3})
    back = through_json(event)
    assert_same_record(event, back)


def test_event_details_numpy_values_become_plain() -> None:
    event = Event(1.0, "k", details={"a": np.arange(3), "b": np.float32(0.5), 7: np.bool_(True)})
    assert encode(event)["details"] == {"a": [0, 1, 2], "b": 0.5, "7": True}


@st.composite
def led_observations(draw: st.DrawFn) -> LedObservation:
    """Observations with any pattern of found / lost LEDs and NaN coordinates."""
    n = draw(st.integers(1, 6))
    pixels, sigma, failures = [], [], []
    for _ in range(n):
        if draw(st.booleans()):
            pixels.append([draw(finite), draw(finite)])
            failures.append(None)
        else:
            row = draw(st.sampled_from([(True, True), (True, False), (False, True)]))
            pixels.append([math.nan if lost else draw(finite) for lost in row])
            failures.append(draw(st.sampled_from(["occluded", "not_in_view", "too_faint"])))
        sigma.append(draw(st.none() | st.floats(0.0, 10.0)))
    sigma_px = [math.nan if s is None else s for s in sigma]
    return LedObservation(
        camera=draw(name),
        child=draw(name),
        timestamp=draw(finite),
        pixels=pixels,
        sigma_px=sigma_px,
        failures=tuple(failures),
        frames=draw(st.integers(0, 100)),
    )


@settings(max_examples=100, deadline=None)
@given(led_observations())
def test_led_observation_nan_patterns_round_trip(obs: LedObservation) -> None:
    encoded = encode(obs)
    json.dumps(encoded, allow_nan=False)  # strict JSON: NaN became null
    back = through_json(obs)
    assert_same_record(obs, back)
    np.testing.assert_array_equal(np.isnan(back.pixels), np.isnan(obs.pixels))
    assert not back.pixels.flags.writeable


def test_nan_and_inf_encode_as_null() -> None:
    obs = LedObservation("cam", "c", 1.0, [[math.nan, 2.0]], [math.inf], ("occluded",))
    encoded = encode(obs)
    assert encoded["pixels"] == [[None, 2.0]]
    assert encoded["sigma_px"] == [None]
    json.dumps(encoded, allow_nan=False)
    assert encode({"x": math.inf, "y": np.float64(-math.inf)}) == {"x": None, "y": None}


def test_encode_adds_type_and_keeps_plain_values() -> None:
    assert encode(TiltReading(1.0, 0.1, -0.2)) == {
        "_type": "TiltReading",
        "timestamp": 1.0,
        "roll": 0.1,
        "pitch": -0.2,
    }
    plain = {"a": [1, "x", None, True], "b": {"c": 2.5}, "t": (1, 2)}
    assert encode(plain) == {"a": [1, "x", None, True], "b": {"c": 2.5}, "t": [1, 2]}


def test_numpy_scalars_become_python_scalars() -> None:
    encoded = encode({"f": np.float32(0.5), "i": np.int64(3), "b": np.bool_(False)})
    assert encoded == {"f": 0.5, "i": 3, "b": False}
    assert [type(v) for v in encoded.values()] == [float, int, bool]


def test_unknown_or_missing_type_decodes_unchanged() -> None:
    unknown = {"_type": "Nope", "x": 1}
    plain = {"x": [1, 2]}
    assert decode(unknown) is unknown
    assert decode(plain) is plain


class _Colour(enum.Enum):
    RED = "red"


@dataclass(frozen=True)
class _Holder:
    value: object


def test_encode_error_names_field_and_type() -> None:
    with pytest.raises(TypeError, match=r"_Holder\.value.*set"):
        encode(_Holder({1, 2}))
    with pytest.raises(TypeError, match=r"details\['bad'\].*complex"):
        encode(Event(1.0, "k", details={"bad": 1j}))
    with pytest.raises(TypeError, match="float"):
        encode(1.5)
    assert encode(_Holder(_Colour.RED)) == {"_type": "_Holder", "value": "red"}


def test_decode_error_names_field_and_type() -> None:
    good = encode(
        DriveResult("a", 1.0, [0, 0, 0], DriveStatus.REACHED, OdometryReading("a", 1, 0, 0, 0), 1)
    )
    with pytest.raises(ValueError, match=r"DriveResult\.status.*'parked'.*DriveStatus"):
        decode({**good, "status": "parked"})
    with pytest.raises(ValueError, match=r"DriveResult\.odometry\.x.*float"):
        decode({**good, "odometry": {**good["odometry"], "x": "far"}})
    with pytest.raises(ValueError, match=r"DriveResult\.duration: missing"):
        decode({k: v for k, v in good.items() if k != "duration"})
    with pytest.raises(ValueError, match=r"DriveResult.*no field.*'speed'"):
        decode({**good, "speed": 1.0})
    with pytest.raises(ValueError, match=r"DriveResult.*goal.*shape"):
        decode({**good, "goal": [1.0, 2.0]})
    with pytest.raises(ValueError, match=r"TiltReading\.roll.*float"):
        decode({"_type": "TiltReading", "timestamp": 0.0, "roll": True, "pitch": 0.0})
