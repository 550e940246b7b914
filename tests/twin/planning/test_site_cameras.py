"""A camera on a wall's face: moved off the box the grid lays the wall as, by the least
distance and by name; a camera deeper in is still refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from tests.twin.planning.test_site import CAMERAS, ORIGIN, PILLAR, write_cameras, write_grid
from twin.cli import main
from twin.planning.boxes import Box, BoxedSpace
from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
from twin.planning.site_cameras import WALL_GAP, clear_cameras
from twin.scenario import load_scenario
from twin.scenario.geometry import inside_obstacles

WALL = (3.0, 5.0, 11.0, 5.2)
"""An inner wall across the room (x0, y0, x1, y1 in the room's coordinates), m."""


def _space(boxes: list[Box], resolution: float = 0.1) -> BoxedSpace:
    return BoxedSpace((0.0, 0.0), (10.0, 10.0, 3.0), tuple(boxes), resolution)


def _floor() -> FloorMap:
    return FloorMap(free=shapely.box(0, 0, 10, 10), obstacles=(), source="floor.yaml")


def _camera(x: float, y: float, z: float = 2.5) -> dict:
    return dict(CAMERAS[0], name="wall", position=[x, y, z])


@pytest.mark.parametrize(
    ("xy", "to"),
    [
        # 4 cm inside the wall's north face (y 5.0 to 5.2): out through it, not the far one.
        ((4.0, 5.16), (4.0, 5.2 + WALL_GAP)),
        ((4.0, 5.04), (4.0, 5.0 - WALL_GAP)),
        # On the face itself (a face belongs to its box).
        ((4.0, 5.2), (4.0, 5.2 + WALL_GAP)),
        # Where the wall crosses a pillar (x 6.0 to 6.2, y 4.6 to 5.6): out of both.
        ((6.17, 5.17), (6.2 + WALL_GAP, 5.2 + WALL_GAP)),
    ],
)
def test_a_camera_just_inside_a_box_moves_out_by_the_least_distance(xy, to):
    wall = Box(center=(5.0, 5.1), size=(6.0, 0.2), height=3.0)
    pillar = Box(center=(6.1, 5.1), size=(0.2, 1.0), height=3.0)
    cameras, moved = clear_cameras(_floor(), [_camera(*xy)], MapPose(), _space([wall, pillar]), 0.0)
    assert cameras[0]["position"][:2] == pytest.approx(to, abs=1e-12)
    assert cameras[0]["position"][2] == 2.5
    assert list(moved) == ["wall"]
    distance = np.hypot(to[0] - xy[0], to[1] - xy[1])
    assert f"moved {distance:.3f} m off it, to ({to[0]:.3f}, {to[1]:.3f})" in moved["wall"]


def test_a_camera_above_a_low_box_or_over_free_floor_stays():
    shelf = Box(center=(5.0, 5.1), size=(6.0, 0.2), height=1.5)
    cameras = [_camera(4.0, 5.1), dict(_camera(2.0, 2.0), name="free")]
    out, moved = clear_cameras(_floor(), cameras, MapPose(), _space([shelf]), 0.0)
    assert out == cameras
    assert moved == {}


def test_a_camera_deeper_than_a_grid_cell_is_refused_by_name():
    block = Box(center=(5.0, 5.0), size=(1.0, 1.0), height=3.0)
    with pytest.raises(MapError) as exc:
        clear_cameras(_floor(), [_camera(5.2, 5.0)], MapPose(), _space([block]), 0.0)
    said = str(exc.value)
    assert "camera 'wall' at (5.20, 5.00), 2.50 m above the floor, stands inside" in said
    assert "more than a grid cell (0.1 m) from its face" in said


def test_a_site_with_a_camera_on_a_walls_face_plans_with_a_warning(tmp_path, capsys):
    # The camera hangs on the wall's north face: the 0.1 m grid lays the wall's box up to
    # 5 cm past it, which the scenario would refuse the camera in.
    grid = write_grid(tmp_path, [PILLAR, WALL])
    on_wall = dict(CAMERAS[0], name="wall", position=[7.0, 5.2, 2.5], view_direction=[0, 1, -0.6])
    cams = write_cameras(tmp_path, [on_wall, CAMERAS[1]])
    out = tmp_path / "site.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict"]) == 0
    said = " ".join(capsys.readouterr().out.split())
    x, y = 7.0 + ORIGIN[0], 5.2 + ORIGIN[1]
    assert f"warning: camera 'wall' at ({x:.2f}, {y:.2f}) it stood inside the blocked floor" in said
    scenario = load_scenario(out)
    camera = next(c for c in scenario.cameras if c.name == "wall")
    assert not inside_obstacles(scenario.space.obstacles, [camera.position[:2]]).any()
    # In the map: moved straight off the face, by no more than the half cell and the gap.
    px, py, yaw = scenario.site.map_pose
    in_map = MapPose(px, py, math.radians(yaw)).world2map(np.asarray(camera.position[:2]))
    assert in_map[0] == pytest.approx(x, abs=1e-9)
    assert y < in_map[1] <= y + 0.05 + WALL_GAP + 1e-9
