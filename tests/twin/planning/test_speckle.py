"""A SLAM map's speckle: small blobs amid free floor read as free, walls and posts kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from shapely.geometry import Point

from twin.planning.floor_map import MapError
from twin.planning.floor_shapes import corridor_turn, write_ros_map
from twin.planning.maps import load_map, polygons_of
from twin.planning.ros_map import FREE, OCCUPIED, SPECKLE_AREA, UNKNOWN, clean_speckle
from twin.planning.site import FORMATION_CLEARANCE

RES = 0.05


def _pieces(path: Path, **options: float) -> list:
    floor = load_map(path, **options)
    assert floor.options == options
    return polygons_of(floor.reachable(FORMATION_CLEARANCE))


def test_flawed_corridor_is_one_piece_after_cleaning(tmp_path: Path):
    """0.2 % of the free cells read occupied cut a 2.4 m corridor at the formation's
    clearance; read as free, the corridor is one piece from its start to its far end."""
    shape = corridor_turn(2.4, 90.0)
    path = write_ros_map(shape, tmp_path, flaws=True, seed=0)
    start, end = Point(1.0, 0.0), Point(12.0, 11.0)  # the way in, the far leg's end
    raw = _pieces(path, speckle=0.0)
    assert not any(p.covers(start) and p.covers(end) for p in raw)
    cleaned = _pieces(path)
    assert len(cleaned) == 1
    assert cleaned[0].covers(start)
    assert cleaned[0].covers(end)
    notes = " ".join(load_map(path).notes)
    assert "speck(s) under speckle = 0.02 m^2" in notes
    # Planned from a chosen start: every camera reachable after cleaning, not before.
    from twin.planning.camera_layout import place_cameras
    from twin.planning.site import plan_site

    cameras = place_cameras(load_map(path), seed=0, height=3.0)
    assert plan_site(load_map(path), cameras, map_file=str(path)).unreachable == {}
    try:
        left_out = plan_site(load_map(path, speckle=0.0), cameras, map_file=str(path)).unreachable
    except MapError as exc:  # no camera reachable from where the group fits
        left_out = str(exc)
    assert left_out


def _room(tmp_path: Path, blob: np.ndarray) -> Path:
    """A 4 x 4 m free room walled by occupied cells, ``blob`` (bool) painted occupied in its
    middle."""
    n = round(4.0 / RES)
    cells = np.full((n, n), 254, dtype=np.uint8)
    cells[[0, -1], :] = 0
    cells[:, [0, -1]] = 0
    r0 = n // 2
    cells[r0 : r0 + blob.shape[0], r0 : r0 + blob.shape[1]][blob] = 0
    import cv2
    import yaml

    cv2.imwrite(str(tmp_path / "room.png"), cells)
    meta = {"image": "room.png", "resolution": RES, "origin": [0.0, 0.0, 0.0]}
    meta |= {"occupied_thresh": 0.65, "free_thresh": 0.196}
    (tmp_path / "room.yaml").write_text(yaml.safe_dump(meta))
    return tmp_path / "room.yaml"


def test_post_above_the_threshold_is_kept(tmp_path: Path):
    post = _room(tmp_path, np.ones((3, 3), bool))  # 0.0225 m^2: a 15 cm post
    floor = load_map(post)
    assert len(floor.obstacles) == 2
    assert floor.obstacles[1].footprint.area == pytest.approx(9 * RES**2)
    assert not any("speck" in n for n in floor.notes)
    # 7 cells (0.0175 m^2) are speckle; with a threshold under their area they stay.
    speck = _room(tmp_path, np.array([[1, 1, 1, 1], [1, 1, 1, 0]], bool))
    assert len(load_map(speck).obstacles) == 1
    assert "0 unknown" in load_map(speck).notes[-1]
    assert "7 occupied" in load_map(speck).notes[-1]
    assert len(load_map(speck, speckle=0.017).obstacles) == 2


@pytest.mark.parametrize("value", [-0.01, float("nan"), float("inf"), "0.02", True, None])
def test_bad_speckle_is_named(tmp_path: Path, value: object):
    path = _room(tmp_path, np.ones((1, 1), bool))
    with pytest.raises(MapError, match=r"speckle: expected an area of at least 0 m\^2"):
        load_map(path, speckle=value)


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.uint8, (12, 14), elements=st.sampled_from([FREE, FREE, FREE, OCCUPIED, UNKNOWN])),
    st.integers(0, 20),
)
def test_cleaning_never_removes_a_wall_cell(cells: np.ndarray, most: int):
    """Every blocked cell 8-connected to the wall (the image's border row, occupied) stays;
    what is removed was blocked, in blobs under ``most`` cells, and only becomes free."""
    import cv2

    cells = cells.copy()
    cells[-1, :] = OCCUPIED  # a wall along the bottom, 14 cells: larger than a speck
    out, blobs, occupied, other = clean_speckle(cells, most)
    blocked = (cells != FREE).astype(np.uint8)
    _, labels = cv2.connectedComponents(blocked, connectivity=8)
    wall = labels == labels[-1, 0]
    np.testing.assert_array_equal(out[wall], cells[wall])
    changed = out != cells
    assert np.all(out[changed] == FREE)
    assert np.count_nonzero(changed) == occupied + other
    assert occupied == np.count_nonzero(changed & (cells == OCCUPIED))
    assert blobs == len(np.unique(labels[changed]))
    edge = set(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]).tolist())
    for label in range(1, labels.max() + 1):
        small = np.count_nonzero(labels == label) < most and label not in edge
        assert np.all(changed[labels == label]) == (small and most > 1)
    assert pytest.approx(8 * RES**2) == SPECKLE_AREA


@pytest.mark.parametrize("value", ["-0.5", "nan", "big"])
def test_site_refuses_a_bad_speckle_by_name(tmp_path: Path, value: str, capsys):
    from twin.cli import main

    out = tmp_path / "site.toml"
    args = ["site", "map.yaml", "--cameras", "c.yaml", "--out", str(out), "--speckle", value]
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    assert "--speckle" in capsys.readouterr().err
    assert not out.exists()


def test_route_past_specks_passes_the_loaders_check(tmp_path: Path):
    """Kept specks (speckle 0) on a 2.4 m corridor: the route passes one at the passage
    clearance, round about the speck but within the loader's square margin of the 0.1 m box
    laid over it; the plan keeps off the boxes as the loader grows them, and validates."""
    from twin.planning.camera_layout import place_cameras
    from twin.planning.floor_shapes import dead_end
    from twin.planning.site import plan_site
    from twin.scenario.loader import scenario_from_dict

    path = write_ros_map(dead_end(2.4), tmp_path, flaws=True, seed=0)
    cameras = place_cameras(load_map(path), seed=0, height=3.0)
    plan = plan_site(load_map(path, speckle=0.0), cameras, map_file=str(path))
    scenario = scenario_from_dict(plan.scenario, file=tmp_path / "site.toml")
    assert len(scenario.route.waypoints) == len(plan.route)


def test_site_reports_the_specks_it_read_as_free(tmp_path: Path, capsys):
    from tests.twin.planning.test_site import CAMERAS, write_cameras, write_grid
    from twin.cli import main

    speck = (6.0, 6.0, 6.05, 6.05)  # one cell amid the room's floor
    grid, cams = write_grid(tmp_path, [speck]), write_cameras(tmp_path, CAMERAS)
    out = tmp_path / "site.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict"]) == 0
    said = " ".join(capsys.readouterr().out.split())
    assert "map: 1 speck(s) under speckle = 0.02 m^2 amid free cells read as free" in said
    assert "1 occupied and 0 unknown cells" in said
