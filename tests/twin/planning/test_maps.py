"""Reading ROS occupancy grids, DXF plans and building meshes into floor maps: maps made
here with a known truth, and every rejection."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import MultiPolygon, Point, Polygon

from twin.planning.floor_map import FloorMap, MapError
from twin.planning.maps import load_map

RES = 0.05  # m per cell of the test grids
CELL = RES * RES

# --------------------------------------------------------------------------------------
# ROS occupancy grid: a 10 x 6 m room (walls 0.2 m, unknown outside), a 1 x 1 m pillar, a
# 0.2 m wall at x = 5.0-5.2 m with a 1 m door at y = 2.5-3.5 m. Room coordinates; the
# room's corner is at (0.4, 0.4) m in the grid frame (lower-left of the image).
# --------------------------------------------------------------------------------------

FREE_PX, OCCUPIED_PX, UNKNOWN_PX = 254, 0, 205
MARGIN = 0.4  # 0.2 m unknown + 0.2 m wall
WIDTH, DEPTH = 10.0, 6.0
PILLAR = (2.0, 3.0, 2.0, 3.0)  # x0, x1, y0, y1 in room coordinates, m
ROOM_A, ROOM_B = (1.0, 5.0), (8.0, 1.0)  # a point in each room, room coordinates


def grid_image(door: bool = True) -> np.ndarray:
    """(H, W) uint8 image of the test room, row 0 at the top."""
    cols = round((WIDTH + 2 * MARGIN) / RES)
    rows = round((DEPTH + 2 * MARGIN) / RES)
    image = np.full((rows, cols), UNKNOWN_PX, dtype=np.uint8)

    def paint(x0: float, x1: float, y0: float, y1: float, value: int) -> None:
        c0, c1 = round(x0 / RES), round(x1 / RES)
        b0, b1 = round(y0 / RES), round(y1 / RES)
        image[rows - b1 : rows - b0, c0:c1] = value

    def room(x0: float, x1: float, y0: float, y1: float, value: int) -> None:
        paint(x0 + MARGIN, x1 + MARGIN, y0 + MARGIN, y1 + MARGIN, value)

    room(-0.2, WIDTH + 0.2, -0.2, DEPTH + 0.2, OCCUPIED_PX)
    room(0.0, WIDTH, 0.0, DEPTH, FREE_PX)
    room(*PILLAR, OCCUPIED_PX)
    room(5.0, 5.2, 0.0, DEPTH, OCCUPIED_PX)
    if door:
        room(5.0, 5.2, 2.5, 3.5, FREE_PX)
    return image


def write_ros(
    folder: Path,
    pixels: np.ndarray | None = None,
    name: str = "map",
    suffix: str = ".pgm",
    **overrides: object,
) -> Path:
    """Write ``<name>.yaml`` and its image (default :func:`grid_image`); ``overrides``
    replace YAML keys (None drops one)."""
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / f"{name}{suffix}"), grid_image() if pixels is None else pixels)
    doc: dict[str, object] = {
        "image": f"{name}{suffix}",
        "resolution": RES,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    for key, value in overrides.items():
        if value is None:
            doc.pop(key, None)
        else:
            doc[key] = value
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def grid2map(xy: tuple[float, float], origin: tuple[float, float, float]) -> np.ndarray:
    """A grid-frame point (m) in the map frame."""
    c, s = math.cos(origin[2]), math.sin(origin[2])
    return np.array([origin[0] + c * xy[0] - s * xy[1], origin[1] + s * xy[0] + c * xy[1]])


def room2map(xy: tuple[float, float], origin: tuple[float, float, float]) -> Point:
    return Point(grid2map((xy[0] + MARGIN, xy[1] + MARGIN), origin))


def same_component(geometry: object, a: Point, b: Point) -> bool:
    parts = list(geometry.geoms) if hasattr(geometry, "geoms") else [geometry]
    return any(p.contains(a) and p.contains(b) for p in parts)


@pytest.mark.parametrize(
    "origin",
    [(0.0, 0.0, 0.0), (-3.25, 12.5, 0.0), (1.0, -2.0, math.pi / 2), (4.0, 1.0, 0.3)],
    ids=["origin", "offset", "yaw90", "yaw0.3"],
)
def test_ros_grid_room_pillar_and_door(tmp_path: Path, origin: tuple[float, float, float]):
    path = write_ros(tmp_path, origin=list(origin))
    floor = load_map(path)
    assert isinstance(floor, FloorMap)
    assert floor.source == str(path)
    assert isinstance(floor.free, Polygon)  # one region: the door joins the rooms
    assert floor.free.is_valid
    expected = WIDTH * DEPTH - 1.0 - 0.2 * (DEPTH - 1.0)
    assert floor.free.area == pytest.approx(expected, abs=CELL)
    # The pillar is a hole of 1 m^2 where it stands in the map frame.
    centre = room2map((2.5, 2.5), origin)
    holes = [Polygon(ring) for ring in floor.free.interiors]
    assert len(holes) == 1
    assert holes[0].area == pytest.approx(1.0, abs=CELL)
    assert holes[0].centroid.distance(centre) < RES
    assert not floor.free.contains(centre)
    assert floor.free.contains(room2map((1.9, 2.5), origin))
    # Both rooms, and a robot with 0.3 m clearance passes the door.
    a, b = room2map(ROOM_A, origin), room2map(ROOM_B, origin)
    assert floor.free.contains(a)
    assert floor.free.contains(b)
    assert same_component(floor.reachable(0.3), a, b)
    # Bounds: the room's corners in the map frame.
    corners = np.array(
        [grid2map((x + MARGIN, y + MARGIN), origin) for x in (0, 10) for y in (0, 6)]
    )
    np.testing.assert_allclose(floor.bounds[:2], corners.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(floor.bounds[2:], corners.max(axis=0), atol=1e-9)
    # Occupied cells: walls (with the interior wall) and the pillar, inf high.
    assert len(floor.obstacles) == 2
    assert all(o.height == math.inf and o.name == "occupied" for o in floor.obstacles)
    walls = 2 * 0.2 * (WIDTH + 0.4) + 2 * 0.2 * DEPTH + 0.2 * (DEPTH - 1.0)
    assert floor.obstacles[0].footprint.area == pytest.approx(walls, abs=CELL)
    assert floor.obstacles[1].footprint.area == pytest.approx(1.0, abs=CELL)
    assert floor.obstacles[1].footprint.centroid.distance(centre) < RES


def test_ros_closed_door_keeps_both_rooms_and_drops_slivers(tmp_path: Path):
    image = grid_image(door=False)
    # A free speck in the unknown margin: smaller than any robot.
    image[1:3, 1:3] = FREE_PX
    floor = load_map(write_ros(tmp_path, image))
    assert isinstance(floor.free, MultiPolygon)
    areas = [p.area for p in floor.free.geoms]
    assert areas == sorted(areas, reverse=True)
    assert areas == pytest.approx([5.0 * 6.0 - 1.0, 4.8 * 6.0], abs=CELL)
    assert not same_component(floor.free, room2map(ROOM_A, (0, 0, 0)), room2map(ROOM_B, (0, 0, 0)))
    assert any("left out" in note and "1 region" in note for note in floor.notes)
    largest = load_map(write_ros(tmp_path, image), keep="largest")
    assert isinstance(largest.free, Polygon)
    assert largest.free.area == pytest.approx(5.0 * 6.0 - 1.0, abs=CELL)


def test_ros_negate_png_and_modes(tmp_path: Path):
    reference = load_map(write_ros(tmp_path / "ref"))
    negated = load_map(write_ros(tmp_path / "neg", 255 - grid_image(), suffix=".png", negate=1))
    assert negated.free.symmetric_difference(reference.free).area < 1e-9
    # scale: the unknown grey (p = 0.196) is of intermediate cost, not free.
    scaled = load_map(write_ros(tmp_path / "scale", mode="scale"))
    assert scaled.free.area == pytest.approx(reference.free.area)
    assert any("intermediate" in note for note in scaled.notes)
    # raw: 0 free, 100 occupied, 255 unknown.
    raw_image = np.select(
        [grid_image() == FREE_PX, grid_image() == OCCUPIED_PX], [0, 100], 255
    ).astype(np.uint8)
    raw = load_map(write_ros(tmp_path / "raw", raw_image, mode="raw"))
    assert raw.free.symmetric_difference(reference.free).area < 1e-9
    # A colour image: the channels' mean.
    colour = cv2.cvtColor(grid_image(), cv2.COLOR_GRAY2BGR)
    rgb = load_map(write_ros(tmp_path / "rgb", colour, suffix=".png"))
    assert rgb.free.symmetric_difference(reference.free).area < 1e-9


def test_ros_large_grid_is_fast(tmp_path: Path):
    import time

    rng = np.random.default_rng(7)
    image = np.full((2000, 2000), FREE_PX, dtype=np.uint8)
    image[:, :20] = image[:, -20:] = image[:20] = image[-20:] = OCCUPIED_PX
    for _ in range(400):
        r, c = rng.integers(40, 1950, size=2)
        h, w = rng.integers(2, 40, size=2)
        image[r : r + h, c : c + w] = rng.choice([OCCUPIED_PX, UNKNOWN_PX])
    path = write_ros(tmp_path, image)
    start = time.perf_counter()
    floor = load_map(path, min_area=0.0)
    elapsed = time.perf_counter() - start
    assert floor.free.area == pytest.approx(int((image == FREE_PX).sum()) * CELL, rel=1e-9)
    assert elapsed < 5.0


@pytest.mark.parametrize("key", ["image", "resolution", "origin", "occupied_thresh", "free_thresh"])
def test_ros_missing_key(tmp_path: Path, key: str):
    path = write_ros(tmp_path, **{key: None})
    with pytest.raises(MapError, match=key) as info:
        load_map(path)
    assert str(path) in str(info.value)
    assert info.value.file == str(path)


@pytest.mark.parametrize("resolution", [0.0, -0.05, "fine", float("nan")])
def test_ros_bad_resolution(tmp_path: Path, resolution: object):
    with pytest.raises(MapError, match="resolution"):
        load_map(write_ros(tmp_path, resolution=resolution))


def test_ros_missing_and_unreadable_image(tmp_path: Path):
    path = write_ros(tmp_path, image="nowhere.pgm")
    with pytest.raises(MapError, match=r"nowhere\.pgm does not exist"):
        load_map(path)
    (tmp_path / "junk.pgm").write_bytes(b"this is not an image")
    with pytest.raises(MapError, match=r"junk\.pgm is not an image"):
        load_map(write_ros(tmp_path, image="junk.pgm"))


@pytest.mark.parametrize(
    ("overrides", "element"),
    [
        ({"origin": [1.0]}, "origin"),
        ({"origin": "zero"}, "origin"),
        ({"mode": "fancy"}, "mode"),
        ({"negate": 2}, "negate"),
    ],
)
def test_ros_bad_fields(tmp_path: Path, overrides: dict, element: str):
    with pytest.raises(MapError, match=element):
        load_map(write_ros(tmp_path, **overrides))


def test_ros_not_yaml(tmp_path: Path):
    path = tmp_path / "map.yaml"
    path.write_text("image: [unclosed\n")
    with pytest.raises(MapError, match="YAML"):
        load_map(path)
    path.write_text("- just\n- a list\n")
    with pytest.raises(MapError, match="mapping"):
        load_map(path)


def test_ros_empty_map(tmp_path: Path):
    image = np.full((40, 40), UNKNOWN_PX, dtype=np.uint8)
    image[10:20, 10:20] = OCCUPIED_PX
    with pytest.raises(MapError, match="no free cell"):
        load_map(write_ros(tmp_path, image))


@pytest.fixture(scope="module")
def small_grid(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a 20 x 20 image: free (255) inside an occupied (0) border."""
    folder = tmp_path_factory.mktemp("thresholds")
    image = np.zeros((20, 20), dtype=np.uint8)
    image[2:-2, 2:-2] = 255
    cv2.imwrite(str(folder / "map.pgm"), image)
    return folder


@settings(max_examples=60, deadline=None)
@given(
    free=st.floats(-0.5, 1.5, allow_nan=False),
    occupied=st.floats(-0.5, 1.5, allow_nan=False),
)
def test_ros_thresholds(small_grid: Path, free: float, occupied: float):
    path = small_grid / "map.yaml"
    doc = {
        "image": "map.pgm",
        "resolution": 0.1,
        "origin": [0, 0, 0],
        "occupied_thresh": occupied,
        "free_thresh": free,
    }
    path.write_text(yaml.safe_dump(doc))
    in_range = 0.0 <= free <= 1.0 and 0.0 <= occupied <= 1.0
    if not in_range:
        with pytest.raises(MapError, match=r"_thresh.*expected a number in \[0, 1\]"):
            load_map(path)
    elif free >= occupied:
        with pytest.raises(MapError, match=r"'free_thresh'.*below 'occupied_thresh'"):
            load_map(path)
    elif free == 0.0:  # a white pixel has p = 0: nothing is below 0
        with pytest.raises(MapError, match="no free cell"):
            load_map(path)
    else:
        floor = load_map(path)
        assert floor.free.area == pytest.approx(1.6 * 1.6)
        assert len(floor.obstacles) == (1 if occupied < 1.0 else 0)


# --------------------------------------------------------------------------------------
# DXF: the same room in mm. The outer wall is a closed polyline (centre line), the
# interior wall with its door two lines, a column a circle, a desk a closed polyline on a
# furniture layer 0.8 m high. Walls 0.15 m thick.
# --------------------------------------------------------------------------------------

COLUMN = ((2500.0, 2500.0), 250.0)  # centre, radius, mm
DESK = (7000.0, 8600.0, 4000.0, 4800.0)  # x0, x1, y0, y1, mm


def write_dxf(path: Path, *, insunits: bool = True, walls: bool = True) -> Path:
    import ezdxf

    doc = ezdxf.new("R2010")
    if insunits:
        doc.units = ezdxf.units.MM
    msp = doc.modelspace()
    for layer in ("A-WALL", "Interior walls", "Columns", "furniture", "Text"):
        doc.layers.add(layer)
    if walls:
        msp.add_lwpolyline(
            [(0, 0), (10000, 0), (10000, 6000), (0, 6000)],
            close=True,
            dxfattribs={"layer": "A-WALL"},
        )
        msp.add_line((5000, 0), (5000, 2500), dxfattribs={"layer": "Interior walls"})
        msp.add_line((5000, 3500), (5000, 6000), dxfattribs={"layer": "Interior walls"})
    msp.add_circle(COLUMN[0], COLUMN[1], dxfattribs={"layer": "Columns"})
    x0, x1, y0, y1 = DESK
    msp.add_lwpolyline(
        [(x0, y0), (x1, y0), (x1, y1), (x0, y1)], close=True, dxfattribs={"layer": "furniture"}
    )
    msp.add_text("Room 101", dxfattribs={"layer": "Text"}).set_placement((1000, 1000))
    doc.saveas(path)
    return path


def test_dxf_walls_column_and_desk(tmp_path: Path):
    path = write_dxf(tmp_path / "plan.dxf")
    floor = load_map(path, heights={"Furniture": 0.8})
    half = 0.075
    inner = (WIDTH - 2 * half) * (DEPTH - 2 * half)
    wall = 2 * half * 2 * (2.5 - half)  # two pieces of interior wall inside the room
    column = math.pi * 0.25**2
    desk = 1.6 * 0.8
    assert isinstance(floor.free, Polygon)
    assert floor.free.is_valid
    assert floor.free.area == pytest.approx(inner - wall - column - desk, abs=5e-3)
    np.testing.assert_allclose(floor.bounds, (half, half, WIDTH - half, DEPTH - half), atol=1e-9)
    # Column and desk where they stand, both rooms joined through the door.
    assert not floor.free.contains(Point(2.5, 2.5))
    assert floor.free.contains(Point(2.5, 2.5 + 0.26))
    assert not floor.free.contains(Point(7.8, 4.4))
    assert same_component(floor.reachable(0.3), Point(1.0, 5.0), Point(8.0, 1.0))
    by_name: dict[str, list] = {}
    for obstacle in floor.obstacles:
        by_name.setdefault(obstacle.name, []).append(obstacle)
    assert set(by_name) == {"A-WALL", "Interior walls", "Columns", "furniture"}
    (desk_obstacle,) = by_name["furniture"]
    assert desk_obstacle.height == pytest.approx(0.8)
    assert desk_obstacle.footprint.area == pytest.approx(desk)
    (column_obstacle,) = by_name["Columns"]
    assert column_obstacle.height == math.inf
    assert column_obstacle.footprint.area == pytest.approx(column, rel=0.02)
    assert column_obstacle.footprint.centroid.distance(Point(2.5, 2.5)) < 1e-6
    assert all(o.height == math.inf for o in by_name["A-WALL"] + by_name["Interior walls"])
    assert any("$INSUNITS = 4" in note for note in floor.notes)
    assert any("Text" in note for note in floor.notes)


def test_dxf_units_option_and_explicit_layers(tmp_path: Path):
    path = write_dxf(tmp_path / "plan.dxf", insunits=False)
    unitless = load_map(path)  # no $INSUNITS: read as metres, 1000 times too large
    assert unitless.free.area == pytest.approx(1e6 * 57.6225, rel=0.05)
    floor = load_map(path, units="mm", wall_layers=["a-wall"], obstacle_layers=["columns"])
    # The interior walls and the desk are not read now.
    assert floor.free.area == pytest.approx(57.6225 - math.pi * 0.25**2, abs=5e-3)
    assert {o.name for o in floor.obstacles} == {"A-WALL", "Columns"}
    thick = load_map(path, units=0.001, wall_thickness=0.3, wall_layers=["A-WALL"])
    assert thick.free.area == pytest.approx(9.7 * 5.7 - math.pi * 0.25**2 - 1.28, abs=5e-3)


def test_dxf_block_references_take_their_layer(tmp_path: Path):
    import ezdxf

    path = write_dxf(tmp_path / "plan.dxf")
    doc = ezdxf.readfile(path)
    block = doc.blocks.new("COLUMN-SMALL")
    block.add_circle((0, 0), 100.0)  # layer 0: takes the reference's layer
    doc.modelspace().add_blockref("COLUMN-SMALL", (8500, 1500), dxfattribs={"layer": "Columns"})
    doc.saveas(path)
    floor = load_map(path)
    columns = [o for o in floor.obstacles if o.name == "Columns"]
    assert len(columns) == 2
    assert not floor.free.contains(Point(8.5, 1.5))
    assert floor.free.contains(Point(8.5, 1.65))


def test_dxf_corrupt(tmp_path: Path):
    path = tmp_path / "broken.dxf"
    path.write_text("0\nSECTION\n2\nENTITIES\n0\nLINE\n8\nwall\n10\nnot-a-number\n")
    with pytest.raises(MapError, match="not a DXF file ezdxf can read") as info:
        load_map(path)
    assert info.value.file == str(path)
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(MapError, match="not a DXF file ezdxf can read"):
        load_map(path)


def test_dxf_no_wall_layer_names_the_layers(tmp_path: Path):
    path = write_dxf(tmp_path / "plan.dxf", walls=False)
    with pytest.raises(MapError, match="no wall") as info:
        load_map(path)
    message = str(info.value)
    assert "the file's layers with entities: Columns (1), Text (1), furniture (1)" in message
    assert "layers with none: 0, A-WALL, Defpoints, Interior walls;" in message
    assert "expected the walls on layers whose name contains 'wall' or holds" in message
    assert message.endswith("with --wall-layers NAME [NAME ...]")
    assert "wall_layers" not in message  # an argument of the Python function only


def test_dxf_units_that_are_no_length_are_named(tmp_path: Path):
    import ezdxf

    path = write_dxf(tmp_path / "plan.dxf")
    doc = ezdxf.readfile(path)
    doc.header["$INSUNITS"] = 19  # light years: no unit of a floor plan
    doc.saveas(path)
    with pytest.raises(MapError) as info:
        load_map(path)
    message = str(info.value)
    assert "header $INSUNITS = 19 is not a length unit; expected a length unit there" in message
    assert "units=" not in message


def test_dxf_walls_enclosing_nothing(tmp_path: Path):
    import ezdxf

    doc = ezdxf.new()
    doc.modelspace().add_line((0, 0), (10, 0), dxfattribs={"layer": "walls"})
    doc.modelspace().add_lwpolyline([(0, 1), (5, 1), (5, 4)], dxfattribs={"layer": "walls"})
    path = tmp_path / "open.dxf"
    doc.saveas(path)
    with pytest.raises(MapError, match="enclose no area") as info:
        load_map(path)
    assert "walls" in str(info.value)


def test_dxf_bad_options(tmp_path: Path):
    path = write_dxf(tmp_path / "plan.dxf")
    with pytest.raises(MapError, match="units"):
        load_map(path, units="furlong")
    with pytest.raises(MapError, match="wall_thickness"):
        load_map(path, wall_thickness=0.0)
    with pytest.raises(MapError, match="keep"):
        load_map(path, keep="biggest")


# --------------------------------------------------------------------------------------
# Mesh: a floor slab (top at z = 0), four walls 0.2 m thick and 3 m high around a
# 10 x 6 m room, a 1 x 2 x 1 m box and a 0.5 x 0.5 x 3 m pillar.
# --------------------------------------------------------------------------------------

BOX = ((3.0, 4.0), (3.0, 5.0), 1.0)  # x range, y range, height (m)
PILLAR_3D = ((7.0, 7.5), (2.0, 2.5), 3.0)


def building(slab: bool = True):
    import trimesh

    def box(x: tuple[float, float], y: tuple[float, float], z: tuple[float, float]):
        extents = [x[1] - x[0], y[1] - y[0], z[1] - z[0]]
        centre = [sum(x) / 2, sum(y) / 2, sum(z) / 2]
        return trimesh.creation.box(
            extents=extents, transform=trimesh.transformations.translation_matrix(centre)
        )

    parts = [
        box((-0.2, 10.2), (-0.2, 0.0), (0.0, 3.0)),  # south wall
        box((-0.2, 10.2), (6.0, 6.2), (0.0, 3.0)),  # north wall
        box((-0.2, 0.0), (-0.2, 6.2), (0.0, 3.0)),  # west wall (overlaps the corners)
        box((10.0, 10.2), (0.0, 6.0), (0.0, 3.0)),  # east wall (touches them)
        box(BOX[0], BOX[1], (0.0, BOX[2])),
        box(PILLAR_3D[0], PILLAR_3D[1], (0.0, PILLAR_3D[2])),
    ]
    if slab:
        parts.append(box((-0.5, 10.5), (-0.5, 6.5), (-0.25, 0.0)))
    return trimesh.util.concatenate(parts)


def check_building(floor: FloorMap, offset: float = 0.0) -> None:
    expected = WIDTH * DEPTH - 2.0 - 0.25
    assert isinstance(floor.free, Polygon)
    assert floor.free.area == pytest.approx(expected, abs=1e-6)
    np.testing.assert_allclose(floor.bounds, (0.0, 0.0, WIDTH, DEPTH), atol=1e-6)
    assert len(floor.free.interiors) == 2
    assert not floor.free.contains(Point(3.5, 4.0))
    assert not floor.free.contains(Point(7.25, 2.25))
    assert floor.height == pytest.approx(3.0 + offset, abs=0.01)
    heights = sorted((round(o.footprint.area, 6), o.height) for o in floor.obstacles)
    assert len(heights) == 3
    (pillar_area, pillar_h), (box_area, box_h), (_, wall_h) = heights
    assert pillar_area == pytest.approx(0.25)
    assert box_area == pytest.approx(2.0)
    assert pillar_h == pytest.approx(3.0, abs=0.01)
    assert box_h == pytest.approx(1.0, abs=0.01)
    assert wall_h == pytest.approx(3.0, abs=0.01)


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply"])
def test_mesh_building(tmp_path: Path, suffix: str):
    path = tmp_path / f"building{suffix}"
    building().export(path)
    floor = load_map(path)
    check_building(floor)
    assert any("floor at z = 0" in note for note in floor.notes)


def test_mesh_glb_y_up_and_units(tmp_path: Path):
    import trimesh

    mesh = building()
    # z-up to y-up (the inverse of up="y"), in mm.
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))
    mesh.apply_scale(1000.0)
    path = tmp_path / "building.glb"
    mesh.export(path)
    check_building(load_map(path, up="y", units="mm"))


def test_mesh_floor_and_section_options(tmp_path: Path):
    path = tmp_path / "building.stl"
    building().export(path)
    # Cut above the box: it is no longer in the plan.
    high = load_map(path, section_height=1.5)
    assert high.free.area == pytest.approx(WIDTH * DEPTH - 0.25, abs=1e-6)
    assert len(high.obstacles) == 2
    # The slab's underside as the floor: heights measured from there.
    import trimesh

    low = load_map(path, floor_z=-0.25)
    box = min((o for o in low.obstacles), key=lambda o: abs(o.footprint.area - 2.0))
    assert box.height == pytest.approx(1.25, abs=0.01)
    # A ceiling slab on top: the room is still air, the walls and the pillar still 3 m.
    ceiling = trimesh.creation.box(
        extents=[11.0, 7.0, 0.25],
        transform=trimesh.transformations.translation_matrix([5.0, 3.0, 3.125]),
    )
    trimesh.util.concatenate([building(), ceiling]).export(tmp_path / "ceiling.stl")
    check_building(load_map(tmp_path / "ceiling.stl"), offset=0.25)
    # No slab: the lowest point is the floor.
    building(slab=False).export(tmp_path / "walls.stl")
    check_building(load_map(tmp_path / "walls.stl"))


def test_mesh_unreadable_and_empty(tmp_path: Path):
    path = tmp_path / "junk.glb"
    path.write_bytes(b"glTF but not really" * 10)
    with pytest.raises(MapError, match="trimesh can read") as info:
        load_map(path)
    assert info.value.file == str(path)
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing here\n")
    with pytest.raises(MapError, match="empty"):
        load_map(empty)


def test_mesh_section_empty_names_the_height(tmp_path: Path):
    path = tmp_path / "building.ply"
    building().export(path)
    with pytest.raises(MapError, match=r"section at z = 10 m .* is empty"):
        load_map(path, section_height=10.0)
    with pytest.raises(MapError, match="section_height"):
        load_map(path, section_height=-1.0)
    with pytest.raises(MapError, match="up"):
        load_map(path, up="x")


def test_mesh_section_enclosing_nothing(tmp_path: Path):
    import trimesh

    path = tmp_path / "pillar.stl"
    trimesh.creation.box(extents=[1, 1, 3]).export(path)
    with pytest.raises(MapError, match="encloses no floor"):
        load_map(path)


# --------------------------------------------------------------------------------------
# The dispatcher.
# --------------------------------------------------------------------------------------


def test_load_map_unknown_extension(tmp_path: Path):
    path = tmp_path / "site.shp"
    path.write_text("")
    with pytest.raises(MapError, match=r"unknown map type '\.shp'.*\.dxf") as info:
        load_map(path)
    assert info.value.file == str(path)
    with pytest.raises(MapError, match="no extension"):
        load_map(tmp_path / "site")


def test_load_map_case_and_yml(tmp_path: Path):
    write_dxf(tmp_path / "PLAN.DXF")
    assert load_map(tmp_path / "PLAN.DXF").free.area > 50.0
    yml = write_ros(tmp_path)
    renamed = yml.with_suffix(".yml")
    yml.rename(renamed)
    assert load_map(renamed).free.area == pytest.approx(58.0, abs=CELL)
    with pytest.raises(TypeError):
        load_map(renamed, section_height=0.3)


def test_a_ragged_floor_shrinks_inside_the_exact_answer_and_once():
    # A 20 x 20 m room whose walls are ragged by 5 cm (8000 vertices, a SLAM map's walls):
    # shrunk after a 5 cm simplification and 5 cm more, in a second (GEOS takes half a
    # minute for the exact answer), inside the exact answer (every point 0.5 m from the
    # walls) and at most 10 cm short of it; asked again, the same geometry comes back.
    import time

    from shapely.geometry import box

    from twin.planning import floor_map

    rng = np.random.default_rng(3)
    side = np.linspace(0.0, 20.0, 2001)[:-1]
    bump = lambda: 0.05 * rng.integers(0, 2, len(side))  # noqa: E731
    ring = np.concatenate(
        [
            np.column_stack([side, bump()]),
            np.column_stack([20.0 - bump(), side]),
            np.column_stack([20.0 - side, 20.0 - bump()]),
            np.column_stack([bump(), 20.0 - side]),
        ]
    )
    free = Polygon(ring)
    assert len(ring) > floor_map.SIMPLIFY_ABOVE
    floor = FloorMap(free=free)
    start = time.perf_counter()
    reach = floor.reachable(0.5)
    assert time.perf_counter() - start < 5.0
    assert floor.reachable(0.5) is reach
    assert free.contains(reach)
    assert free.boundary.distance(reach.boundary) >= 0.5 - 1e-9
    assert reach.contains(box(0.65, 0.65, 19.35, 19.35))
