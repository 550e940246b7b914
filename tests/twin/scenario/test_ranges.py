"""Absurd numbers get an error naming the key, the value and the accepted range; NaN and
infinity are refused everywhere; a large but plausible site loads."""

from __future__ import annotations

import copy
import math
import time
import tomllib
import types
import typing
from typing import Annotated, Any

import annotated_types
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel, Field

from twin.instruments.marker import MarkerAssembly
from twin.scenario import Scenario, ScenarioError, load_scenario, scenario_from_dict
from twin.scenario.loader import validate_model

from .helpers import SCENARIOS, variant

SMOKE = tomllib.loads((SCENARIOS / "smoke.toml").read_text(encoding="utf-8"))
WALKER = {"name": "walker", "waypoints": [[0.0, 2.0], [3.0, 2.0]]}
MARKER = {
    "cubes": MarkerAssembly().cubes_body.tolist(),
    "leds": MarkerAssembly().leds_body.tolist(),
}

# (key path, the accepted range as the error says it). One or more of each class of
# field: lengths, heights, coordinates, angles, tilts, intrinsics, image sizes, noise
# figures, marker geometry, seeds, the timestep, speeds.
FIELDS = [
    (("space", "size", 0), "a number in [1, 5000]"),
    (("space", "size", 2), "a number in [1, 1000]"),
    (("space", "obstacles", 0, "size", 0), "a number in [0.01, 5000]"),
    (("space", "obstacles", 0, "size", 2), "a number in [0.01, 1000]"),
    (("space", "obstacles", 0, "center", 1), "a number in [-5000, 5000]"),
    (("space", "obstacles", 0, "yaw_deg"), "a number in [-360, 360]"),
    (("space", "floor_patches", 0, "tilt_arcmin", 1), "a number in [-60, 60]"),
    (("space", "wall_thickness"), "a number in [0.01, 2]"),
    (("space", "lighting", "spacing"), "a number in (1, 5000]"),
    (("cameras", 0, "position", 0), "a number in [-5000, 5000]"),
    (("cameras", 0, "view_direction", 2), "a number in [-10000, 10000]"),
    (("cameras", 0, "f"), "a number in [1, 100000]"),
    (("cameras", 0, "cx"), "a number in [-4096, 8192]"),
    (("cameras", 0, "kappa1"), "a number in [-0.1, 0.1]"),
    (("cameras", 0, "sx"), "a number in (0.5, 2)"),
    (("cameras", 0, "image_size", 0), "an integer in [8, 4096]"),
    (("cameras", 0, "sensor", "read_noise_e"), "a number in [0, 1000]"),
    (("robots", "children", 0, "start_yaw_deg"), "a number in [-360, 360]"),
    (("marker", "cubes", 0, 0), "a number in [-1, 1]"),
    (("marker", "leds", 3, 2), "a number in [0.25, 2.5]"),
    (("noise", "total_station", "angle_sigma"), "a number in [0, 0.001]"),
    (("noise", "total_station", "range_max"), "a number in (0, 10000]"),
    (("noise", "inclinometer", "sigma"), "a number in [0, 0.001]"),
    (("noise", "odometry", "heading_noise"), "a number in [0, 0.1]"),
    (("noise", "led_detection_px"), "a number in [0, 10]"),
    (("route", "waypoints", 1, 0), "a number in [-5000, 5000]"),
    (("calibration", "visits", 0, "station", 0), "a number in [-5000, 5000]"),
    (("calibration", "visits", 0, "yaw_deg"), "a number in [-360, 360]"),
    (("people", 0, "speed"), "a number in [0.1, 3]"),
    (("people", 0, "start_offset"), "a number in [0, 20000]"),
    (("campaign", "pixel_size_mm"), "a number in [0.0005, 0.1]"),
    (("sim", "timestep"), "a number in [0.0002, 0.01]"),
    (("seed",), "an integer in [0, 9223372036854775807]"),
]


def _key(path: tuple[Any, ...]) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else ("." if out else "") + part
    return out


def _with(path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    """The smoke scenario (with a walking person and its marker written out) with ``value``
    at ``path``."""
    raw = copy.deepcopy(SMOKE | {"people": [WALKER], "marker": MARKER})
    node: Any = raw
    for part in path[:-1]:
        node = node.setdefault(part, {}) if isinstance(part, str) else node[part]
    node[path[-1]] = value
    return raw


def _issue_at(raw: dict[str, Any], key: str):
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(raw)
    issues = [i for i in info.value.issues if i.key == key]
    assert issues, f"{key} not among {[i.key for i in info.value.issues]}"
    return issues[0], str(info.value)


def _keys_of_issues(raw: dict[str, Any]) -> list[str]:
    try:
        scenario_from_dict(raw)
    except ScenarioError as err:
        return [i.key for i in err.issues]
    return []


def _interval(expected: str) -> tuple[float, bool, float, bool]:
    """(lo, lo included, hi, hi included) of "a number in [lo, hi)" and the like (ints for
    "an integer in [lo, hi]")."""
    number = int if expected.startswith("an integer") else float
    text = expected.split(" in ")[1]
    lo, hi = text[1:-1].split(", ")
    return number(lo), text[0] == "[", number(hi), text[-1] == "]"


def _outside(expected: str) -> st.SearchStrategy:
    lo, lo_in, hi, hi_in = _interval(expected)
    if expected.startswith("an integer"):
        return st.integers(max_value=lo - 1) | st.integers(min_value=hi + 1)
    below = st.floats(max_value=lo, exclude_max=lo_in)
    above = st.floats(min_value=hi, exclude_min=hi_in)
    return below | above | st.just(math.nan)


def _inside(expected: str) -> st.SearchStrategy:
    lo, lo_in, hi, hi_in = _interval(expected)
    if expected.startswith("an integer"):
        return st.integers(min_value=lo, max_value=hi)
    return st.floats(min_value=lo, max_value=hi, exclude_min=not lo_in, exclude_max=not hi_in)


ABSURD = [
    (("space", "size", 0), 1e308),  # the hall of the hardening issue
    (("cameras", 0, "f"), 1e308),  # the focal length of the hardening issue
    (("space", "obstacles", 0, "size", 2), 2000.0),
    (("cameras", 0, "position", 0), -1e6),
    (("calibration", "visits", 0, "yaw_deg"), 1e308),
    (("space", "floor_patches", 0, "tilt_arcmin", 1), 600.0),
    (("cameras", 0, "cx"), 1e9),
    (("cameras", 0, "kappa1"), 1.0),
    (("cameras", 0, "image_size", 0), 100_000),
    (("noise", "total_station", "angle_sigma"), 1.0),
    (("noise", "odometry", "heading_noise"), -0.1),
    (("marker", "cubes", 0, 0), 5.0),
    (("people", 0, "speed"), 100.0),
    (("sim", "timestep"), 1.0),
    (("seed",), -1),
    (("seed",), 2**64),
]


@pytest.mark.parametrize(("path", "value"), ABSURD, ids=[_key(p) for p, _ in ABSURD])
def test_an_absurd_number_is_refused_with_its_key_value_and_range(path, value):
    expected = dict(FIELDS)[path]
    issue, message = _issue_at(_with(path, value), _key(path))
    assert issue.value == value
    assert issue.expected == expected
    assert f"{_key(path)}: " in message
    assert f"(got {value!r})" in message
    assert expected in message


@pytest.mark.parametrize(
    ("path", "items", "expected"),
    [
        (("cameras",), 1001, "1 to 1000 items"),
        (("calibration", "visits"), 5001, "1 to 5000 items"),
        (("route", "waypoints"), 10_001, "2 to 10000 items"),
        (("space", "obstacles"), 1001, "at most 1000 items"),
        (("people",), 201, "at most 200 items"),
        (("robots", "children"), 9, "1 to 8 items"),
    ],
)
def test_too_many_items_are_refused_with_the_accepted_count(path, items, expected):
    template = {
        ("cameras",): SMOKE["cameras"][0],
        ("calibration", "visits"): SMOKE["calibration"]["visits"][0],
        ("route", "waypoints"): [1.0, 0.0],
        ("space", "obstacles"): SMOKE["space"]["obstacles"][0],
        ("people",): WALKER,
        ("robots", "children"): SMOKE["robots"]["children"][0],
    }[path]
    many = [copy.deepcopy(template) for _ in range(items)]
    issue, message = _issue_at(_with(path, many), _key(path))
    assert issue.expected == expected
    assert f"not {items}" in issue.problem
    assert f"{items} items)" in message  # the long value is cut short, its length named
    assert len(message) < 1000


def test_an_inclinometer_noisier_than_a_tenth_of_its_range_is_refused():
    # 1 mrad of noise in a 3 arc-minute (0.87 mrad) range: a level instrument would read
    # out of range.
    issue, _ = _issue_at(_with(("noise", "inclinometer", "sigma"), 1e-3), "noise.inclinometer")
    assert "more than a tenth of working_range" in issue.problem
    assert issue.expected == "sigma at most 8.72665e-05 rad"


def test_a_route_longer_than_10_km_is_refused():
    raw = _with(("space", "size"), [4000.0, 6.0, 3.0])
    raw["route"]["waypoints"] = [[0.0, 0.0], [3990.0, 0.0], [0.0, 0.0], [3990.0, 0.0]]
    issue, _ = _issue_at(raw, "route.waypoints")
    assert issue.problem == "the path is 11970 m long"
    assert issue.expected == "a path at most 10000 m long"


@pytest.mark.parametrize(("path", "expected"), FIELDS, ids=[_key(p) for p, _ in FIELDS])
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_any_number_outside_a_range_is_refused_with_the_key_named(path, expected, data):
    value = data.draw(_outside(expected))
    issue, _ = _issue_at(_with(path, value), _key(path))
    assert repr(issue.value) == repr(value)
    assert issue.expected == expected


@pytest.mark.parametrize(("path", "expected"), FIELDS, ids=[_key(p) for p, _ in FIELDS])
@settings(max_examples=10, deadline=None)
@given(data=st.data())
def test_a_number_inside_its_range_raises_no_issue_at_its_key(path, expected, data):
    value = data.draw(_inside(expected))
    assert _key(path) not in _keys_of_issues(_with(path, value))


@pytest.mark.parametrize("literal", ["nan", "inf", "-inf", "+inf"])
@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("f = 400.0", "f = {}", "cameras[0].f"),
        ("cx = 159.5", "cx = {}", "cameras[0].cx"),
        ("size = [10.0, 6.0, 3.0]", "size = [10.0, {}, 3.0]", "space.size[1]"),
        ("start_xy = [1.5, 1.5]", "start_xy = [{}, 1.5]", "robots.children[0].start_xy[0]"),
        (
            "tilt_arcmin = [0.0, 3.0]",
            "tilt_arcmin = [{}, 3.0]",
            "space.floor_patches[0].tilt_arcmin[0]",
        ),
        (
            "[route]",
            "[noise.total_station]\nrange_min = {}\n\n[route]",
            "noise.total_station.range_min",
        ),
    ],
)
def test_nan_and_infinity_are_refused_in_toml(tmp_path, literal, old, new, key):
    path = variant(tmp_path, "nonfinite", [(old, new.format(literal))])
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    issue = next(i for i in info.value.issues if i.key == key)
    assert issue.problem == "not a finite number"
    assert issue.expected.startswith("a number in ")
    assert repr(issue.value) == repr(float(literal))
    assert str(path) in str(info.value)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_nan_and_infinity_are_refused_in_yaml_and_in_unbounded_lists(tmp_path, value):
    raw = copy.deepcopy(SMOKE)
    raw["cameras"][0]["opencv_distortion"] = [0.0, 0.0, 0.0, value]
    raw["noise"] = {"marker_geometry_m": value}
    path = tmp_path / "nonfinite.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    keys = [i.key for i in info.value.issues]
    assert keys == ["cameras[0].opencv_distortion[3]", "noise.marker_geometry_m"]


def _unwrap(annotation: Any) -> tuple[Any, list[Any]]:
    constraints: list[Any] = []
    while True:
        args = typing.get_args(annotation)
        if typing.get_origin(annotation) is Annotated:
            annotation = args[0]
            for extra in args[1:]:
                constraints += getattr(extra, "metadata", [extra])
        elif typing.get_origin(annotation) in (typing.Union, types.UnionType):
            annotation = next(a for a in args if a is not type(None))
        else:
            return annotation, constraints


def _unbounded(model: type[BaseModel], prefix: str = "") -> list[str]:
    """Keys of ``model``'s numbers without both bounds and of its lists without a longest
    length (every one a number or a list a scenario could make absurd)."""
    out = []
    for name, field in model.model_fields.items():
        out += _unbounded_value(field.annotation, list(field.metadata), f"{prefix}{name}")
    return out


def _unbounded_value(annotation: Any, constraints: list[Any], key: str) -> list[str]:
    annotation, more = _unwrap(annotation)
    constraints = constraints + more
    kinds = {type(c) for c in constraints}
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return _unbounded(annotation, f"{key}.")
    if annotation in (float, int):
        low = kinds & {annotated_types.Ge, annotated_types.Gt}
        high = kinds & {annotated_types.Le, annotated_types.Lt}
        return [] if low and high else [key]
    if typing.get_origin(annotation) is tuple:
        args = typing.get_args(annotation)
        variadic = len(args) == 2 and args[1] is Ellipsis
        out = [key] if variadic and annotated_types.MaxLen not in kinds else []
        for i, arg in enumerate(args[:1] if variadic else args):
            out += _unbounded_value(arg, [], f"{key}[{i}]")
        return out
    return []


def test_every_number_and_list_of_the_schema_is_bounded():
    # opencv_distortion has 4, 5 or 8 coefficients, which its own validator checks.
    assert _unbounded(Scenario) == ["cameras[0].opencv_distortion"]


def _large_site() -> dict[str, Any]:
    """A 2 km x 1 km site: a 3 km route, 300 cameras each visited once, a row of
    buildings, people."""
    raw = copy.deepcopy(SMOKE)
    raw["space"] = {
        "size": [2000.0, 1000.0, 60.0],
        "origin": [-20.0, -500.0],
        "floor_z": -0.40,
        "obstacles": [
            {"name": f"building{i}", "center": [100.0 * i, 300.0], "size": [60.0, 40.0, 50.0]}
            for i in range(1, 20)
        ],
    }
    xs = [5.0 + 6.3 * i for i in range(300)]
    raw["cameras"] = [
        {
            "name": f"cam{i}",
            "position": [x, 2.0, 2.1],
            "view_direction": [0.0, -1.0, -0.5],
            "f": 400.0,
            "cx": 159.5,
            "cy": 119.5,
            "image_size": [320, 240],
        }
        for i, x in enumerate(xs)
    ]
    raw["route"] = {"waypoints": [[0.0, 0.0], [1900.0, 0.0], [1900.0, 100.0], [900.0, 100.0]]}
    raw["calibration"] = {
        "visits": [{"camera": f"cam{i}", "station": [x, 0.0]} for i, x in enumerate(xs)]
    }
    raw["people"] = [
        {"name": f"walker{i}", "waypoints": [[0.0, 50.0 + i], [1000.0, 50.0 + i]]}
        for i in range(20)
    ]
    return raw


def test_a_large_but_plausible_site_loads():
    start = time.perf_counter()
    sc = scenario_from_dict(_large_site())
    took = time.perf_counter() - start
    assert sc.space.size[:2] == (2000.0, 1000.0)
    assert sc.route.length == pytest.approx(3000.0)
    assert len(sc.cameras) == len(sc.calibration.visits) == 300
    assert took < 30.0, f"validating the large site took {took:.1f} s"


def test_a_render_larger_than_the_renderer_takes_is_refused():
    raw = _with(("cameras", 0, "image_size"), [4096, 8])
    raw["cameras"][0] |= {"cx": 2047.5, "cy": 3.5, "f": 2000.0, "sensor": {"supersample": 8}}
    issue, _ = _issue_at(raw, "cameras[0].sensor")
    assert "rendered 32768 px wide" in issue.problem
    assert issue.expected == "supersample at most 4 for this image"


def test_the_largest_image_may_be_supersampled_up_to_the_renderer_s_limit():
    raw = _with(("cameras", 0, "image_size"), [4096, 3072])
    raw["cameras"][0] |= {"cx": 2047.5, "cy": 1535.5, "f": 5000.0, "sensor": {"supersample": 4}}
    assert "cameras[0].sensor" not in _keys_of_issues(raw)


def test_a_site_section_names_its_keys_and_its_range():
    # [site] is optional: its keys and ranges are read through the "| None".
    issue, message = _issue_at(SMOKE | {"site": {"map": "m.yaml", "bogus": 1}}, "site.bogus")
    assert issue.expected == "one of: map, map_pose, resolution"
    issue, message = _issue_at(
        SMOKE | {"site": {"map": "m.yaml", "resolution": 0}}, "site.resolution"
    )
    assert "site.resolution: too small (got 0); expected a number in (0, 10]" in message
    issue, _ = _issue_at(SMOKE | {"site": {"map": "m.yaml", "resolution": 11}}, "site.resolution")
    assert (issue.problem, issue.expected) == ("too large", "a number in (0, 10]")


class _OneSided(BaseModel):
    above: Annotated[float, Field(gt=0.0)] = 1.0
    at_least: Annotated[int, Field(ge=2)] = 2
    below: Annotated[float, Field(lt=5.0)] = 1.0
    at_most: Annotated[float, Field(le=0.5)] = 0.0
    by_name: dict[str, Annotated[float, Field(gt=0.25)]] = {}
    # Constraints the schema cannot be walked to: the error's own bound is named.
    counts: dict[str, Annotated[int, Field(le=3)]] = {}


@pytest.mark.parametrize(
    ("data", "key", "problem", "expected"),
    [
        ({"above": 0.0}, "above", "too small", "a number above 0"),
        ({"at_least": 1}, "at_least", "too small", "an integer of at least 2"),
        ({"below": 5.0}, "below", "too large", "a number below 5"),
        ({"at_most": 0.75}, "at_most", "too large", "a number of at most 0.5"),
        ({"above": math.nan}, "above", "not a finite number", "a number above 0"),
        ({"by_name": {"a": 0.1}}, "by_name.a", "too small", "a number above 0.25"),
        ({"counts": {"b": 4}}, "counts.b", "too large", "an integer of at most 3"),
    ],
)
def test_every_kind_of_range_reads_in_words(data, key, problem, expected):
    with pytest.raises(ScenarioError) as info:
        validate_model(_OneSided, data, "numbers.toml")
    (issue,) = info.value.issues
    assert (issue.key, issue.problem, issue.expected) == (key, problem, expected)
    assert "Input should" not in str(info.value)
    assert str(info.value).startswith("numbers.toml: ")
