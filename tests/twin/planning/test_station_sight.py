"""A camera's station on a floor where a wall stands between the camera and part of its
floor view (a U-turn: two corridors side by side): the station is chosen for the floor the
camera itself sees, and a station from which the child finds no data stop is passed over."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin.campaign.plan.accurate_stops import partial_view_stops
from twin.planning import floor_shapes
from twin.planning.boxes import boxed_space
from twin.planning.frames import MapPose
from twin.planning.site_stations import map_space
from twin.planning.stations import REACHED, NoStationError, choose_station
from twin.scenario.loader import validate_model
from twin.scenario.robots import INSTRUMENT_HEIGHT
from twin.scenario.schema import CameraConfig, MarkerConfig, Noise

WIDTH = 2.4
"""The corridors' width, m: the first runs along y = 0, the way back along y = 2.6."""

WALL_Y = 0.5 * WIDTH
"""The wall between the two corridors starts here, m."""

FLOOR_Z = -INSTRUMENT_HEIGHT
MARKER = MarkerConfig()
RANGE = (Noise().total_station.range_min, Noise().total_station.range_max)
PRISM_HEIGHT = float(np.mean([c[2] for c in MARKER.cubes]))


@pytest.fixture(scope="module")
def site():
    free = floor_shapes.u_turn(WIDTH)
    space = map_space(boxed_space(floor_shapes.floor_map(free), MapPose(), 0.1), FLOOR_Z)
    return space, free.buffer(-0.45)


def ceiling_camera(yaw_deg: float):
    """A camera 3 m up at the first corridor's side, looking 30 degrees down and
    ``yaw_deg`` from the corridor towards the wall (a ceiling camera as installed)."""
    y, t = math.radians(yaw_deg), math.radians(30.0)
    cfg = {
        "name": "cam",
        "position": [1.0, -0.9, FLOOR_Z + 3.0],
        "view_direction": [math.cos(t) * math.cos(y), math.cos(t) * math.sin(y), -math.sin(t)],
        "f": 300.0,
        "cx": 159.5,
        "cy": 119.5,
        "image_size": [320, 240],
    }
    return validate_model(CameraConfig, cfg).tsai()


def station(space, reachable, camera, **kwargs):
    return choose_station(
        "cam",
        camera,
        space,
        reachable,
        instrument_z=0.0,
        prism_height=PRISM_HEIGHT,
        instrument_range=RANGE,
        need=0.25,
        **kwargs,
    )


def stops(space, camera, xy):
    return partial_view_stops(space, MARKER.assembly(), RANGE, camera, xy, 0.0, None)


def test_the_station_sees_the_floor_the_camera_sees_not_the_floor_behind_its_wall(site):
    # Most of the view's floor lies in the other corridor, behind the wall from the camera:
    # a station there would see no child the camera sees.
    space, reachable = site
    camera = ceiling_camera(60.0)
    chosen = station(space, reachable, camera)
    assert chosen.xy[1] < WALL_Y
    assert len(stops(space, camera, chosen.xy)) >= 6


def test_a_camera_that_sees_only_a_wall_gets_no_station(site):
    space, reachable = site
    with pytest.raises(NoStationError, match=r"at best 0 %"):
        station(space, reachable, ceiling_camera(85.0))


def test_a_station_from_which_no_stop_works_is_passed_over(site):
    space, reachable = site
    camera = ceiling_camera(70.0)
    first = station(space, reachable, camera)
    chosen = station(space, reachable, camera, gives_data=lambda xy: bool(stops(space, camera, xy)))
    assert stops(space, camera, chosen.xy)
    assert not np.allclose(chosen.xy, first.xy)
    with pytest.raises(NoStationError, match=r"leaves a child a place in it .* tried"):
        station(space, reachable, camera, gives_data=lambda xy: False)


def test_a_station_the_children_reach_the_stops_from_is_preferred(site):
    # The first station that gives data but stands between the children and its stops
    # is kept only where no later one lets them pass.
    space, reachable = site
    camera = ceiling_camera(70.0)
    first = station(space, reachable, camera, gives_data=lambda xy: 1)
    reached = station(
        space,
        reachable,
        camera,
        gives_data=lambda xy: 1 if np.allclose(xy, first.xy) else REACHED,
    )
    assert not np.allclose(reached.xy, first.xy)
    assert reached.visible <= first.visible
    # Where none lets them pass, the first that gives data: the best.
    assert np.allclose(first.xy, station(space, reachable, camera).xy)
