"""``twin site`` before the route: the ceiling, the floor the robots reach from the start,
the start itself, and the DXF's wall layers; each refusal names its culprit."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, box

from tests.twin.planning.test_site import CAMERAS, ORIGIN, PILLAR, write_cameras, write_grid
from twin.cli import main
from twin.planning.ceiling import CEILING_MARGIN, LOWEST_CEILING, site_ceiling
from twin.planning.dxf_map import is_wall_layer
from twin.planning.floor_map import FloorMap
from twin.planning.maps import load_map
from twin.planning.regions import CHILD_CLEARANCE, children_at, group_start
from twin.planning.site import PASSAGE_CLEARANCE
from twin.scenario import load_scenario


def site(grid: Path, cams: Path, out: Path, *extra: str) -> int:
    """``twin site`` without the geometric run (the plan alone)."""
    return main(
        ["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict", *extra]
    )


def said(capsys) -> str:
    return " ".join(capsys.readouterr().out.split())


# --------------------------------------------------------------------------------------
# Ceiling
# --------------------------------------------------------------------------------------


def test_cameras_at_3_m_plan_under_the_default_ceiling_and_a_lower_one_is_refused(tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    high = [dict(c, position=[*c["position"][:2], 3.0]) for c in CAMERAS]
    cams = write_cameras(tmp_path, high)
    out = tmp_path / "site.toml"
    assert site(grid, cams, out) == 0
    sc = load_scenario(out)
    assert sc.space.size[2] == pytest.approx(3.0 + CEILING_MARGIN)
    assert {c.name for c in sc.cameras} == {"cam1", "cam2"}
    low = tmp_path / "low.toml"
    assert site(grid, cams, low, "--ceiling-height", "2.9") == 2
    message = said(capsys).split("error:")[1]
    for name in ("'cam1' at 3.00 m", "'cam2' at 3.00 m", "ceiling, 2.90 m", "--ceiling-height"):
        assert name in message
    assert not low.exists()
    assert not low.with_suffix(".plan.png").exists()
    # A ceiling given above the cameras is the scenario's.
    assert site(grid, cams, low, "--ceiling-height", "4.2") == 0
    assert load_scenario(low).space.size[2] == pytest.approx(4.2)


@settings(max_examples=50, deadline=None)
@given(
    heights=st.lists(st.floats(0.1, 20.0), min_size=1, max_size=5),
    own=st.one_of(st.none(), st.floats(1.0, 30.0)),
    given_height=st.one_of(st.none(), st.floats(1.0, 30.0)),
)
def test_the_ceiling_is_the_given_then_the_maps_then_above_the_cameras(heights, own, given_height):
    floor = FloorMap(box(0, 0, 5, 5), height=own or 3.0, height_known=own is not None)
    cameras = [{"name": f"c{k}", "position": [1.0, 1.0, h]} for k, h in enumerate(heights)]
    ceiling = site_ceiling(floor, cameras, given_height)
    if given_height is not None:
        assert ceiling == given_height
    elif own is not None:
        assert ceiling == own
    else:
        assert ceiling >= LOWEST_CEILING
        assert ceiling == pytest.approx(max(LOWEST_CEILING, max(heights) + CEILING_MARGIN))
        assert ceiling > max(heights)


# --------------------------------------------------------------------------------------
# Connectivity: islands and narrow passages
# --------------------------------------------------------------------------------------


def test_a_camera_on_a_separate_room_is_named_and_the_rest_planned(tmp_path, capsys):
    # A wall without a door splits the room; cam1 looks into the right half.
    grid = write_grid(tmp_path, [(6.9, 0.0, 7.1, 8.0)])
    cams = write_cameras(tmp_path)
    out = tmp_path / "site.toml"
    assert site(grid, cams, out) == 1
    text = said(capsys)
    line = re.search(r"cam1 at \(([-\d.]+), ([-\d.]+)\): (.*?)(?: scenario|$)", text)
    assert line, text
    assert (float(line[1]), float(line[2])) == (12.0 + ORIGIN[0], 4.0 + ORIGIN[1])
    why = re.search(r"separate piece of floor, ([\d.]+) m\^2 around \(([-\d.]+), ([-\d.]+)\)", text)
    assert why, text
    # The right half: x 7.1 to 14, y 0 to 8 in the room's coordinates (5 cm cells).
    assert float(why[1]) == pytest.approx(6.9 * 8.0, abs=0.5)
    assert float(why[2]) == pytest.approx(10.55 + ORIGIN[0], abs=0.1)
    assert float(why[3]) == pytest.approx(4.0 + ORIGIN[1], abs=0.1)
    assert "cam2" not in text.split("warning:")[1]
    sc = load_scenario(out)
    assert [c.name for c in sc.cameras] == ["cam2"]
    assert [v.camera for v in sc.calibration.visits] == ["cam2"]
    # Visits of the unreachable camera alone: nothing to plan, refused by name.
    only = tmp_path / "only.toml"
    assert site(grid, cams, only, "--visits", "cam1") == 2
    assert "the robots can reach no camera of the visits given: cam1 at (9.00, 6.00)" in said(
        capsys
    )
    assert not only.exists()


def test_a_camera_behind_a_passage_narrower_than_the_robots_is_named_with_the_place(
    tmp_path, capsys
):
    # The same wall with a 0.6 m door at y = 3.7 to 4.3 (room coordinates).
    grid = write_grid(tmp_path, [(6.9, 0.0, 7.1, 3.7), (6.9, 4.3, 7.1, 8.0)])
    cams = write_cameras(tmp_path)
    out = tmp_path / "site.toml"
    assert site(grid, cams, out) == 1
    text = said(capsys)
    found = re.search(
        r"cam1 at \([-\d.]+, [-\d.]+\): its floor view lies beyond a passage ([\d.]+) m wide "
        r"at \(([-\d.]+), ([-\d.]+)\), narrower than the ([\d.]+) m the robots need",
        text,
    )
    assert found, text
    assert float(found[1]) == pytest.approx(0.6, abs=0.06)
    assert float(found[2]) == pytest.approx(7.0 + ORIGIN[0], abs=0.1)
    assert float(found[3]) == pytest.approx(4.0 + ORIGIN[1], abs=0.1)
    assert float(found[4]) == pytest.approx(2 * PASSAGE_CLEARANCE, abs=0.005)
    assert [c.name for c in load_scenario(out).cameras] == ["cam2"]


# --------------------------------------------------------------------------------------
# Start
# --------------------------------------------------------------------------------------

DEPOT = box(0.0, 0.0, 30.0, 15.0)
"""An open depot's free floor, m."""


@pytest.mark.parametrize("corner", [(29.2, 14.2), (0.8, 0.8), (29.2, 0.8), (0.8, 14.2)])
@pytest.mark.parametrize("yaw_deg", [0.0, 90.0, -135.0])
def test_both_children_find_room_beside_a_start_in_a_corner_of_an_open_depot(corner, yaw_deg):
    free = DEPOT.buffer(-CHILD_CLEARANCE)
    yaw = math.radians(yaw_deg)
    children = children_at(free, corner, yaw)
    assert children is not None
    c, s = math.cos(yaw), math.sin(yaw)
    for child in children:
        turned = np.array([c * child[0] - s * child[1], s * child[0] + c * child[1]])
        assert free.covers(LineString([corner, corner + turned]))
        assert 1.2 - 1e-9 <= np.linalg.norm(child) <= 2.7
    assert np.linalg.norm(children[0] - children[1]) >= 1.0


def test_no_room_for_the_children_and_the_nearest_start_that_has(tmp_path):
    # A 2 m wide room joined to a large one by a corridor 1.0 m wide: a child cannot stand
    # 1.2 m from the centre of the small room in sight of it.
    small = Point(0.0, 0.0).buffer(1.0)
    free = small.union(box(0.0, -0.5, 6.0, 0.5)).union(box(6.0, -3.0, 12.0, 3.0))
    child_free = free.buffer(-CHILD_CLEARANCE)
    assert children_at(child_free, (0.0, 0.0), 0.0) is None
    place = group_start(free.buffer(-0.7), child_free, (0.0, 0.0))
    assert place is not None
    assert children_at(child_free, place, 0.0) is not None
    assert place[0] == pytest.approx(6.7, abs=0.3)  # the large room's nearest corner


def test_a_refused_start_gives_its_place_and_a_start_that_works(tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    out = tmp_path / "site.toml"
    corner = (0.2 + ORIGIN[0], 0.2 + ORIGIN[1])
    assert site(grid, cams, out, "--start", str(corner[0]), str(corner[1]), "30") == 2
    text = said(capsys)
    assert f"the start ({corner[0]:.2f}, {corner[1]:.2f}) in the map's frame" in text
    hint = re.search(r"try --start ([-\d.]+) ([-\d.]+) 30", text)
    assert hint, text
    assert not out.exists()
    assert site(grid, cams, out, "--start", hint[1], hint[2], "30") == 0
    pose = load_scenario(out).site.map_pose
    assert pose[:2] == pytest.approx([float(hint[1]), float(hint[2])])


def test_a_start_on_a_piece_no_camera_looks_at_is_refused_with_a_start_that_works(tmp_path, capsys):
    grid = write_grid(tmp_path, [(6.9, 0.0, 7.1, 8.0)])
    cams = write_cameras(tmp_path, [CAMERAS[1]])  # cam2 looks at the left half
    out = tmp_path / "site.toml"
    right = (10.0 + ORIGIN[0], 5.0 + ORIGIN[1])
    assert site(grid, cams, out, "--start", str(right[0]), str(right[1]), "0") == 2
    text = said(capsys)
    assert f"the start ({right[0]:.2f}, {right[1]:.2f}) in the map's frame is on a piece" in text
    hint = re.search(r"try --start ([-\d.]+) ([-\d.]+) 0", text)
    assert hint, text
    assert float(hint[1]) < 6.9 + ORIGIN[0]


def test_the_automatic_start_in_an_open_depot_has_room_for_the_group(tmp_path):
    grid = write_grid(tmp_path, [])
    corners = [
        dict(CAMERAS[0], name="cam1", position=[13.5, 7.5, 3.0], view_direction=[-1, -1, -1.2]),
        dict(CAMERAS[0], name="cam2", position=[0.5, 0.5, 3.0], view_direction=[1, 1, -1.2]),
    ]
    cams = write_cameras(tmp_path, corners)
    out = tmp_path / "site.toml"
    assert site(grid, cams, out) == 0
    sc = load_scenario(out)
    assert len(sc.robots.children) == 2
    assert sc.space.size[2] == pytest.approx(3.5)


# --------------------------------------------------------------------------------------
# DXF layers
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name",
    [
        "A-WALL",
        "A-WALL-FULL",
        "Interior walls",
        "Wände_tragend",
        "WÄNDE",
        "Innenwand",
        "Außenwände",
        "Mauer",
        "MUR-porteur",
        "cloisons",
        "Muro",
        "paredes exteriores",
        "tabique",
        "pareti_interne",
        "muri",
    ],
)
def test_common_names_of_wall_layers_are_recognised(name):
    assert is_wall_layer(name)


@pytest.mark.parametrize("name", ["0", "Text", "Wandschrank", "Möbel", "murphy", "prepared"])
def test_other_layers_are_not_walls(name):
    assert not is_wall_layer(name)


def write_plan(path: Path, walls: str, inner: str) -> Path:
    """A 10 x 6 m room (metres) with its outer walls on ``walls`` and an inner wall with a
    2 m door on ``inner``, and a text on its own layer."""
    import ezdxf

    doc = ezdxf.new("R2010")
    doc.units = ezdxf.units.M
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 6), (0, 6)], close=True, dxfattribs={"layer": walls})
    msp.add_line((5, 0), (5, 2), dxfattribs={"layer": inner})
    msp.add_line((5, 4), (5, 6), dxfattribs={"layer": inner})
    msp.add_text("Raum 1", dxfattribs={"layer": "Beschriftung"}).set_placement((1, 1))
    doc.saveas(path)
    return path


def test_german_wall_layers_are_read(tmp_path):
    floor = load_map(write_plan(tmp_path / "plan.dxf", "Wände_tragend", "Innenwand"))
    assert {o.name for o in floor.obstacles} == {"Wände_tragend", "Innenwand"}
    assert floor.free.area == pytest.approx(9.85 * 5.85 - 2 * 0.15 * (2 - 0.075), abs=0.01)
    assert not floor.height_known


def test_unknown_wall_layers_are_listed_and_named_by_the_option(tmp_path, capsys):
    plan = write_plan(tmp_path / "plan.dxf", "Umriss", "Trennlinie")
    cam = dict(CAMERAS[0], position=[8.0, 3.0, 2.5], view_direction=[-1.0, 0.0, -0.8])
    cams = tmp_path / "cameras.yaml"
    cams.write_text(yaml.safe_dump([cam]))
    out = tmp_path / "site.toml"
    assert site(plan, cams, out) == 2
    text = said(capsys)
    assert "layers with entities: Beschriftung (1), Trennlinie (2), Umriss (1)" in text
    assert "--wall-layers NAME [NAME ...]" in text
    assert not out.exists()
    assert site(plan, cams, out, "--wall-layers", "umriss", "TRENNLINIE") == 0
    assert load_scenario(out).cameras[0].name == "cam1"


def test_layer_options_on_a_map_that_is_no_dxf_are_refused(tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    out = tmp_path / "site.toml"
    assert site(grid, cams, out, "--obstacle-layers", "Columns") == 2
    assert "--obstacle-layers: a DXF map's layers" in said(capsys)
    assert not out.exists()


def test_a_camera_above_a_meshs_own_ceiling_is_refused_naming_the_maps_height():
    from twin.planning.ceiling import check_ceiling
    from twin.planning.floor_map import MapError

    floor = FloorMap(box(0, 0, 5, 5), height=2.6, height_known=True, source="hall.glb")
    cameras = [{"name": "low", "position": [1, 1, 2.5]}, {"name": "top", "position": [1, 1, 2.8]}]
    with pytest.raises(MapError) as info:
        check_ceiling(floor, cameras, site_ceiling(floor, cameras), given=False)
    message = str(info.value)
    assert "'top' at 2.80 m" in message
    assert "'low'" not in message
    assert "2.60 m (the map's own height)" in message


def test_a_view_on_floor_narrower_than_the_robots_is_named_with_its_place():
    from twin.planning.regions import floor_pieces, unreachable_why, view_counts

    # A 10 x 6 m room and a 1 m wide dead-end corridor off it, x 10 to 16.
    floor = FloorMap(box(0, 0, 10, 6).union(box(9.9, 2.5, 16, 3.5)))
    pieces = floor_pieces(floor.reachable(0.7))
    assert len(pieces) == 1
    view = np.column_stack([np.linspace(13, 15, 20), np.full(20, 3.0)])
    counts = view_counts(pieces, {"c": view}, 0.7)["c"]
    why = unreachable_why(floor, pieces, 0, counts, view, 0.7)
    assert why == (
        "its floor view lies on floor narrower than the robots need (1.40 m) around (14.00, 3.00)"
    )
    inside = np.array([[5.0, 3.0], [6.0, 3.0]])
    assert (
        unreachable_why(floor, pieces, 0, view_counts(pieces, {"c": inside}, 0.7)["c"], inside, 0.7)
        is None
    )
