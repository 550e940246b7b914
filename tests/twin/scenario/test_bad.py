"""A bad scenario gets an error naming the file, the key and what was expected."""

from __future__ import annotations

import pytest

from twin.scenario import ScenarioError, load_scenario

from .helpers import variant


def _error(path) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.file == str(path)
    assert str(path) in str(err)
    return err


def _only(err: ScenarioError, key: str):
    keys = [i.key for i in err.issues]
    assert key in keys, f"{key} not among {keys}"
    return next(i for i in err.issues if i.key == key)


def test_misspelt_key(tmp_path):
    path = variant(tmp_path, "misspelt", [("[[space.obstacles]]", "[[space.obstacels]]")])
    issue = _only(_error(path), "space.obstacels")
    assert issue.problem == "unknown key"
    assert "obstacles" in issue.expected
    assert "floor_patches" in issue.expected
    assert "space.obstacels: unknown key" in str(_error(path))


def test_misspelt_key_in_an_array_of_tables(tmp_path):
    path = variant(tmp_path, "misspelt2", [("view_direction =", "view_dirction =")])
    err = _error(path)
    issue = _only(err, "cameras[0].view_dirction")
    assert "view_direction" in issue.expected
    # The correctly spelt key is now missing, and that is reported too.
    assert _only(err, "cameras[0].view_direction").problem == "missing"


def test_wrong_type(tmp_path):
    path = variant(tmp_path, "wrongtype", [("f = 400.0", 'f = "400"')])
    issue = _only(_error(path), "cameras[0].f")
    assert issue.value == "400"
    assert issue.expected == "a number"


def test_wrong_length(tmp_path):
    path = variant(tmp_path, "wronglen", [("size = [10.0, 6.0, 3.0]", "size = [10.0, 6.0]")])
    _only(_error(path), "space.size[2]")


def test_camera_outside_the_space(tmp_path):
    path = variant(
        tmp_path, "camout", [("position = [6.0, 0.0, 1.6]", "position = [9.0, 0.0, 1.6]")]
    )
    issue = _only(_error(path), "cameras[0].position")
    assert "outside the space" in issue.problem
    assert issue.value == [9.0, 0.0, 1.6]
    assert "x in [-2, 8]" in issue.expected


def test_camera_above_the_ceiling(tmp_path):
    path = variant(
        tmp_path, "camhigh", [("position = [6.0, 0.0, 1.6]", "position = [6.0, 0.0, 3.0]")]
    )
    assert "outside the space" in _only(_error(path), "cameras[0].position").problem


def test_route_through_a_wall(tmp_path):
    path = variant(
        tmp_path,
        "routewall",
        [
            (
                "waypoints = [[0.0, 0.0], [4.0, 0.0]]",
                "waypoints = [[0.0, 0.0], [4.0, 0.0], [4.0, 5.0]]",
            )
        ],
    )
    issue = _only(_error(path), "route.waypoints[1]")
    assert "segment 1->2" in issue.problem
    assert "wall" in issue.problem
    assert issue.expected == "a route inside the space"


def test_a_route_that_does_not_start_at_the_parent_is_refused(tmp_path):
    path = variant(
        tmp_path,
        "routestart",
        [("waypoints = [[0.0, 0.0], [4.0, 0.0]]", "waypoints = [[1.0, 0.0], [4.0, 0.0]]")],
    )
    issue = _only(_error(path), "route.waypoints[0]")
    assert "the route starts 1.00 m from the parent's start [0.0, 0.0]" in issue.problem
    assert issue.value == [1.0, 0.0]
    assert "starts where the parent does" in issue.expected
    near = variant(
        tmp_path,
        "routenear",
        [("waypoints = [[0.0, 0.0], [4.0, 0.0]]", "waypoints = [[0.3, 0.0], [4.0, 0.0]]")],
    )
    assert load_scenario(near).route.waypoints[0] == (0.3, 0.0)


def test_route_through_an_obstacle(tmp_path):
    path = variant(
        tmp_path,
        "routeobst",
        [
            (
                "waypoints = [[0.0, 0.0], [4.0, 0.0]]",
                "waypoints = [[0.0, 0.0], [6.5, -1.0], [6.5, -2.5]]",
            )
        ],
    )
    err = _error(path)
    issues = [i for i in err.issues if i.key.startswith("route.waypoints")]
    assert any("pillar" in i.problem for i in issues)


SCREENS = """[[space.obstacles]]
name = "screen"
center = [0.5, 1.8]
size = [3.0, 0.2, 3.0]

[[space.obstacles]]
name = "screen2"
center = [2.5, 0.0]
size = [0.2, 3.2, 3.0]

[[space.floor_patches]]"""


def test_station_that_cannot_see_the_camera_view(tmp_path):
    # Two tall screens between the station and the camera's view of the floor.
    path = variant(
        tmp_path,
        "blocked",
        [
            ("[[space.floor_patches]]", SCREENS),
            ("start_xy = [1.5, 1.5]", "start_xy = [1.5, 2.4]"),
        ],
    )
    err = _error(path)
    issue = _only(err, "calibration.visits[0].station")
    assert "sees only" in issue.problem
    assert "cam1" in issue.problem
    assert "min_visible_fraction" in issue.expected


def test_station_too_far_for_the_instrument(tmp_path):
    path = variant(
        tmp_path, "toofar", [("[route]", "[noise.total_station]\nrange_max = 1.5\n\n[route]")]
    )
    issue = _only(_error(path), "calibration.visits[0].station")
    assert "sees only 5 %" in issue.problem


def test_unknown_camera_in_a_visit(tmp_path):
    path = variant(tmp_path, "unknowncam", [('camera = "cam1"', 'camera = "cam9"')])
    issue = _only(_error(path), "calibration.visits[0].camera")
    assert issue.value == "cam9"
    assert "cam1" in issue.expected


def test_instrument_spec_rejects_inconsistent_values(tmp_path):
    path = variant(
        tmp_path,
        "badspec",
        [("[route]", "[noise.total_station]\nrange_min = 5.0\nrange_max = 2.0\n\n[route]")],
    )
    issue = _only(_error(path), "noise.total_station")
    assert "range_max" in issue.problem


def test_toml_syntax_error(tmp_path):
    path = variant(tmp_path, "syntax", [("seed = 1", "seed = = 1")])
    issue = _only(_error(path), "<syntax>")
    assert "line" in issue.problem


def test_every_problem_is_reported_at_once(tmp_path):
    path = variant(tmp_path, "several", [("seed = 1", "seed = -1"), ("f = 400.0", "f = -400.0")])
    keys = {i.key for i in _error(path).issues}
    assert {"seed", "cameras[0].f"} <= keys


def test_duplicate_names(tmp_path):
    path = variant(tmp_path, "dup", [('name = "child2"', 'name = "child1"')])
    assert "repeated: child1" in str(_error(path))


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ('name = "pillar"', 'name = "floor"', "space.obstacles[0].name"),
        ('name = "pillar"', 'name = "wall_north"', "space.obstacles[0].name"),
        ('name = "tilted"', 'name = "wall_top"', "space.floor_patches[0].name"),
    ],
)
def test_reserved_geom_names(tmp_path, old, new, key):
    path = variant(tmp_path, "reserved", [(old, new)])
    issue = _only(_error(path), key)
    assert "reserved" in issue.problem
    assert issue.value == new.split('"')[1]
    assert "floor and wall_*" in issue.expected


def test_obstacle_and_patch_share_a_name(tmp_path):
    path = variant(tmp_path, "dupgeom", [('name = "tilted"', 'name = "pillar"')])
    issue = _only(_error(path), "space.floor_patches[0].name")
    assert "repeated: pillar" in issue.problem
    assert issue.value == "pillar"


def test_robot_start_footprints_overlap(tmp_path):
    path = variant(tmp_path, "overlap", [("start_xy = [1.5, 1.5]", "start_xy = [0.3, 0.0]")])
    issue = _only(_error(path), "robots.children[0].start_xy")
    assert "'child1' overlaps that of 'parent'" in issue.problem
    assert issue.value == [0.3, 0.0]
    assert "apart" in issue.expected


def test_robots_may_start_close_side_by_side(tmp_path):
    # Bumper to bumper with 0.13 m between them: their enclosing circles overlap, their
    # footprints do not.
    path = variant(tmp_path, "close", [("start_xy = [1.5, 1.5]", "start_xy = [0.6, 0.0]")])
    assert load_scenario(path).robots.children[0].start_xy == (0.6, 0.0)


def test_a_robot_may_not_start_in_the_corner_of_an_obstacles_clearance(tmp_path):
    # The pillar (0.6 m square at (6.5, -2.2)) grown by a child's radius, 0.29 m, is a
    # square: (7.07, -1.63) lies within 0.29 m of the pillar along both axes, though
    # 0.82 m from its centre, farther than its corners (0.42 m) and the radius together.
    path = variant(tmp_path, "corner", [("start_xy = [1.5, 1.5]", "start_xy = [7.07, -1.63]")])
    issue = _only(_error(path), "robots.children[0].start_xy")
    assert "lies inside obstacle 'pillar'" in issue.problem


def test_parent_must_start_at_the_world_origin(tmp_path):
    path = variant(
        tmp_path,
        "parentoff",
        [
            ("start_xy = [0.0, 0.0]", "start_xy = [0.5, 0.0]\nstart_yaw_deg = 10.0"),
            ("floor_z = -0.40", "floor_z = -0.30"),
        ],
    )
    err = _error(path)
    xy = _only(err, "robots.parent.start_xy")
    assert "instrument frame" in xy.problem
    assert xy.value == [0.5, 0.0]
    assert xy.expected.startswith("[0.0, 0.0]")
    yaw = _only(err, "robots.parent.start_yaw_deg")
    assert yaw.value == 10.0
    assert yaw.expected.startswith("0.0")
    floor = _only(err, "space.floor_z")
    assert floor.value == -0.30
    assert floor.expected == "-0.40"


def test_floor_patch_overlapping_an_obstacle(tmp_path):
    path = variant(tmp_path, "patchobst", [("center = [3.0, -1.5]", "center = [6.0, -2.2]")])
    issue = _only(_error(path), "space.floor_patches[0].center")
    assert "overlaps obstacle 'pillar'" in issue.problem
    assert issue.value == [6.0, -2.2]


def test_obstacle_lower_than_the_ground_clearance(tmp_path):
    path = variant(tmp_path, "low", [("size = [0.6, 0.6, 3.0]", "size = [0.6, 0.6, 0.06]")])
    issue = _only(_error(path), "space.obstacles[0].size")
    assert "drive over it unseen" in issue.problem
    assert issue.value == [0.6, 0.6, 0.06]
    assert issue.expected == "an obstacle taller than 0.08 m"


def test_stairs_whose_first_step_is_below_the_ground_clearance(tmp_path):
    stairs = '[[space.obstacles]]\nname = "steps"\nkind = "stairs"\nsteps = 50\n'
    stairs += "center = [-1.0, -2.0]\nsize = [1.0, 1.0, 3.0]\n\n[[space.floor_patches]]"
    path = variant(tmp_path, "lowstep", [("[[space.floor_patches]]", stairs)])
    issue = _only(_error(path), "space.obstacles[1].size")
    assert "its lowest step" in issue.problem
    assert "step taller than 0.08 m" in issue.expected


CAMERA_LINE = "image_size = [320, 240]"
ROUTE_LINE = "[route]"


@pytest.mark.parametrize(
    ("anchor", "added", "key", "problem"),
    [
        (
            CAMERA_LINE,
            "opencv_distortion = [0.1, 0.0, 0.0]",
            "cameras[0].opencv_distortion",
            "4, 5 or 8 coefficients",
        ),
        (
            CAMERA_LINE,
            "kappa1 = 1e-7\nopencv_distortion = [0.1, 0.0, 0.0, 0.0]",
            "cameras[0]",
            "either kappa1",
        ),
        (CAMERA_LINE, "sensor = { supersample = 0 }", "cameras[0].sensor.supersample", ""),
        (CAMERA_LINE, "sensor = { bits = 7 }", "cameras[0].sensor.bits", ""),
        (
            ROUTE_LINE,
            '[[people]]\nname = "walker"\nwaypoints = [[0.0, 2.0], [0.0, 9.0]]\n',
            "people[0].waypoints[0]",
            "walks through a wall",
        ),
        (
            ROUTE_LINE,
            '[[people]]\nname = "child1"\nwaypoints = [[0.0, 2.0], [3.0, 2.0]]\n',
            "people[0].name",
            "unique",
        ),
        ("floor_z = -0.40", "lighting = { flicker = 0.9 }", "space.lighting.flicker", ""),
    ],
)
def test_bad_camera_sensor_lighting_and_people(tmp_path, anchor, added, key, problem):
    # The line is added after the anchor (before it for a table header).
    new = f"{added}\n{anchor}" if anchor.startswith("[") else f"{anchor}\n{added}"
    issue = _only(_error(variant(tmp_path, "bad", [(anchor, new)])), key)
    assert problem in issue.problem


def test_a_file_that_is_not_utf8_is_refused_naming_the_byte(tmp_path):
    path = variant(tmp_path, "latin1", [])
    path.write_bytes(path.read_bytes() + b"# caf\xe9\n")
    issue = _only(_error(path), "<file>")
    assert "is not UTF-8 text" in issue.problem
    assert "line" in issue.problem


def test_a_byte_order_mark_is_read_past(tmp_path):
    path = variant(tmp_path, "bom", [])
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert load_scenario(path).name == load_scenario(variant(tmp_path, "plain", [])).name


def test_a_yaml_scenario_that_repeats_a_key_is_refused(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text("name: a\nname: b\n", encoding="utf-8")
    issue = _only(_error(path), "<syntax>")
    assert "a second time" in issue.problem


def _with_control_point(tmp_path, name: str, position: list[float], pillar_height: float = 3.0):
    point = f'[[control_points]]\nname = "{name}"\nposition = {position}\n\n{ROUTE_LINE}'
    pillar = ("size = [0.6, 0.6, 3.0]", f"size = [0.6, 0.6, {pillar_height}]")
    return variant(tmp_path, name, [(ROUTE_LINE, point), pillar])


def test_a_control_point_inside_an_obstacle_is_refused_naming_both(tmp_path):
    # The smoke room's pillar: centre (6.5, -2.2), 0.6 m square, its top at z = 2.6 m.
    err = _error(_with_control_point(tmp_path, "prism", [6.6, -2.1, 0.0]))
    issue = _only(err, "control_points[0].position")
    assert issue.problem == (
        "control point 'prism' lies inside obstacle 'pillar' (below its top, z = 2.6 m)"
    )
    assert issue.value == [6.6, -2.1, 0.0]
    assert issue.expected == "a position on free floor or above the obstacle"
    # Beside it, or on top of a pillar 1 m high (its top at z = 0.6 m): points to be seen.
    load_scenario(_with_control_point(tmp_path, "beside", [6.5, -1.85, 0.0]))
    load_scenario(_with_control_point(tmp_path, "on_top", [6.5, -2.2, 0.7], 1.0))
    err = _error(_with_control_point(tmp_path, "under", [6.5, -2.2, 0.5], 1.0))
    assert "(below its top, z = 0.6 m)" in _only(err, "control_points[0].position").problem


def test_an_unknown_strategy_is_refused_naming_the_known_ones(tmp_path):
    path = variant(tmp_path, "bold", [("[route]", '[campaign]\nstrategy = "bold"\n\n[route]')])
    err = _error(path)
    issue = _only(err, "campaign.strategy")
    assert issue.problem == "unknown strategy"
    assert issue.value == "bold"
    assert issue.expected == "a strategy the campaign knows: paper, planned"
    assert "campaign.strategy: unknown strategy (got 'bold')" in str(err)


@pytest.mark.parametrize("name", ["paper", "planned"])
def test_each_known_strategy_is_accepted(tmp_path, name):
    path = variant(tmp_path, name, [("[route]", f'[campaign]\nstrategy = "{name}"\n\n[route]')])
    assert load_scenario(path).campaign.strategy == name


def test_a_route_through_an_obstacle_names_the_segment_and_the_obstacle(tmp_path):
    path = variant(
        tmp_path,
        "routepillar",
        [
            (
                "waypoints = [[0.0, 0.0], [4.0, 0.0]]",
                "waypoints = [[0.0, 0.0], [4.0, 0.0], [4.0, -2.2], [7.0, -2.2]]",
            )
        ],
    )
    issue = _only(_error(path), "route.waypoints[2]")
    assert "segment 2->3 runs through obstacle 'pillar' (or closer than" in issue.problem
    assert issue.expected == "a route clear of the obstacles"
    assert issue.value == [[4.0, -2.2], [7.0, -2.2]]
