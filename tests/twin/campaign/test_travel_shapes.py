"""CPS travel through the shapes real buildings are hard at: a turn into a narrow
corridor, a sharper turn, a U-turn, a dead-end room in and back out, a doorway. Each is
planned on a generated floor (:mod:`twin.planning.floor_shapes`) with a camera an
installer would hang past the hard spot (3 m up, looking 30 degrees down) and run
noise-free at the geometric fidelity: the camera must be calibrated where the truth puts
it. A passage narrower than the parent is named before any run."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from twin.planning import floor_shapes as fs
from twin.planning.floor_map import MapError
from twin.planning.maps import load_map
from twin.planning.site import PASSAGE_CLEARANCE, plan_site
from twin.run.runner import run_scenario
from twin.scenario.loader import scenario_from_dict

LEG = 12.0
"""Length of each leg of the generated corridors, m."""

EXACT_MM = 1.0
"""A noise-free campaign's camera position error, at most, mm: the CPS chain and the
calibration are exact but for rounding and the Tsai fit's convergence."""


def camera(name: str, xy, toward, height: float = 3.0, down_deg: float = 30.0) -> dict:
    """A camera ``height`` m up at ``xy`` looking towards ``toward`` (map frame, m),
    ``down_deg`` below the horizontal."""
    d = np.asarray(toward, dtype=float) - np.asarray(xy, dtype=float)
    d /= np.linalg.norm(d)
    return {
        "name": name,
        "position": [float(xy[0]), float(xy[1]), height],
        "view_direction": [float(d[0]), float(d[1]), -math.tan(math.radians(down_deg))],
        "f": 300.0,
        "cx": 159.5,
        "cy": 119.5,
        "image_size": [320, 240],
    }


def lobby(free, top: float = 2.5):
    """``free`` with a 4 x 5 m room at its way in, where the group starts."""
    return shapely.union_all([free, box(-3.0, -2.5, 1.0, top)])


def turn(deg: float):
    a = math.radians(deg)
    end = np.array([LEG + LEG * math.cos(a), LEG * math.sin(a)])
    back = -np.array([math.cos(a), math.sin(a)])  # from the end towards the turn
    right = np.array([math.sin(a), -math.cos(a)])  # of the way on, looking along it
    cam = camera("past_turn", end + 0.5 * back + 0.9 * right, end + 5.0 * back)
    return fs.corridor_turn(2.4, deg, LEG), [cam], (1.5, 0.0, 0.0)


SHAPES = {
    "turn_90": lambda: turn(90.0),
    "turn_135": lambda: turn(135.0),
    # The way back runs behind a wall beside the way out; the camera looks along it.
    "u_turn": lambda: (
        shapely.union_all([fs.u_turn(2.4, LEG), box(-4.0, -3.5, 1.0, 1.2)]),
        [camera("way_back", (1.0, 3.4), (6.0, 2.6))],
        (-2.0, -1.0, 0.0),
    ),
    # The camera at the way back's far end looks along it to the start: its station is
    # in the lobby, and the child drives round the robots standing there into the way back.
    "way_back_from_lobby": lambda: (
        lobby(fs.corridor_turn(2.4, 180.0, LEG)),
        [camera("far_leg", (0.58, 3.26), (5.97, 1.95))],
        (-1.5, 0.0, 0.0),
    ),
    # A room behind a 1.2 m door halfway along a blind corridor, then its far end: in and
    # back out.
    "dead_end": lambda: (
        fs.dead_end(2.4, 16.0, (5.0, 4.0), 1.2),
        [camera("room", (8.0, 5.1), (8.0, 1.9)), camera("blind_end", (15.5, 0.9), (11.0, 0.0))],
        (1.5, 0.0, 0.0),
    ),
    "doorway_1m": lambda: (
        fs.doorway((8.0, 6.0), 1.0),
        [camera("second_room", (14.3, 0.3), (9.0, 0.0))],
        (0.0, 0.0, 0.0),
    ),
}


def plan(shape: str, folder):
    """The shape's plan, its map written in ``folder`` as a ROS map (a scenario references
    its map file), and its cameras' names."""
    free, cameras, start = SHAPES[shape]()
    floor = load_map(fs.write_ros_map(free, folder, name=shape))
    names = [c["name"] for c in cameras]
    planned = plan_site(floor, cameras, name=shape, start=start, visits=names, ceiling_height=4.0)
    # A short campaign: no reference data sets, a small data set at each station.
    planned.scenario["campaign"] = {"reference_cameras": [], "station_points": 40}
    return planned, names


@pytest.mark.parametrize("shape", list(SHAPES))
def test_a_camera_past_a_hard_spot_is_calibrated_noise_free(shape, tmp_path):
    planned, names = plan(shape, tmp_path)
    scenario = scenario_from_dict(planned.scenario, file=tmp_path / f"{shape}.toml")
    results = run_scenario(
        scenario, tmp_path / "run", fidelity="geometric", noise=False, report=False
    )
    assert results["failures"].get("campaign_aborted", 0) == 0, results["failures"]
    assert [c["camera"] for c in results["calibrations"]] == names
    for cal in results["calibrations"]:
        assert cal["truth"]["position_error_mm"] < EXACT_MM, (cal["camera"], cal["truth"])


def test_the_dead_end_route_goes_into_the_room_and_back_out(tmp_path):
    planned, _ = plan("dead_end", tmp_path)
    route = planned.route
    inside = route[:, 1] > 1.2 + fs.WALL  # W is the map moved 1.5 m along x
    enters = np.flatnonzero(inside)
    assert enters.size
    assert enters[-1] < len(route) - 1
    assert not inside[-1]


def test_a_passage_narrower_than_the_parent_is_named_before_any_run():
    door = 2 * PASSAGE_CLEARANCE - 0.3
    free = fs.doorway((8.0, 6.0), door)
    with pytest.raises(
        MapError, match=r"beyond a passage [\d.]+ m wide at \(6\.[56]\d, -?0\.\d+\), narrower"
    ):
        plan_site(
            fs.floor_map(free, height=4.0),
            [camera("second_room", (14.3, 0.3), (9.0, 0.0))],
            start=(0.0, 0.0, 0.0),
        )
