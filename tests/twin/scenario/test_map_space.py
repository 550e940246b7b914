"""A space that references its map (``[space.map]``): a floor of more boxes than a
scenario may hold loads and plans, a missing or changed map is refused by name with
nothing written, the boxes are not written back, and MuJoCo collides a U-shaped room's
walls as they are."""

from __future__ import annotations

import math
import pickle
import re
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest
import shapely
import yaml
from shapely.geometry import Point, Polygon, box

from twin.cli import main
from twin.planning.boxes import boxed_space
from twin.planning.floor_map import FloorMap
from twin.planning.frames import MapPose
from twin.planning.map_files import map_sha256
from twin.scenario import load_scenario
from twin.scenario.digest import scenario_digest
from twin.scenario.limits import MAX_OBSTACLES
from twin.scenario.map_space import map_obstacle

CELL = 0.05
"""The generated maps' cell, m."""


def toothed_floor(folder: Path, teeth: bool = True) -> tuple[Path, Path]:
    """A 24 x 7 m room as a ROS map, its long walls combed (``teeth``) with teeth 1.5 m
    long every 0.25 m whose width zigzags every 0.1 m (as a SLAM map's rough shelving
    does): more boxes than a scenario may hold. A 4 m band runs clear between the teeth's
    tips; one camera looks along it."""
    folder.mkdir(parents=True, exist_ok=True)
    w, h = round(24.4 / CELL), round(7.4 / CELL)
    image = np.full((h, w), 254, np.uint8)
    image[:4, :] = image[-4:, :] = 0
    image[:, :4] = image[:, -4:] = 0
    for x in np.arange(0.3, 23.8, 0.25) if teeth else ():
        c = round((x + 0.2) / CELL)
        for k in range(15):  # along the tooth, 0.1 m at a time: 0.1 then 0.2 m wide
            width = 2 if k % 2 else 4
            for y in (0.1 * k, 7.0 - 0.1 * (k + 1)):
                r1 = h - round((y + 0.2) / CELL)
                image[r1 - 2 : r1, c : c + width] = 0
    cv2.imwrite(str(folder / "map.pgm"), image)
    meta = {
        "image": "map.pgm",
        "resolution": CELL,
        "origin": [-0.2, -0.2, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta))
    camera = {
        "name": "cam1",
        "position": [16.0, 3.5, 2.5],
        "view_direction": [-1.0, 0.0, -0.6],
        "f": 400.0,
        "cx": 159.5,
        "cy": 119.5,
        "image_size": [320, 240],
    }
    (folder / "cameras.yaml").write_text(yaml.safe_dump([camera]))
    return folder / "map.yaml", folder / "cameras.yaml"


@pytest.fixture(scope="module")
def big_site(tmp_path_factory) -> Path:
    """A site planned on the room without its teeth, then its map combed (the planner's
    geometry queries take long over a thousand boxes; loading and running do not): the
    scenario's hash is the combed map's."""
    folder = tmp_path_factory.mktemp("big")
    grid, cameras = toothed_floor(folder / "maps", teeth=False)
    out = folder / "sites" / "big.toml"
    args = ["site", str(grid), "--cameras", str(cameras), "--out", str(out), "--no-predict"]
    assert main(args) == 0
    plain = map_sha256(grid)
    toothed_floor(folder / "maps")
    out.write_text(out.read_text().replace(plain, map_sha256(grid)))
    return out


def test_a_floor_of_more_boxes_than_a_scenario_holds_loads(big_site):
    raw = tomllib.loads(big_site.read_text())
    # The file references its map (relative to the scenario's folder) and holds no box.
    assert raw["space"]["map"]["file"] == "../maps/map.yaml"
    assert "obstacles" not in raw["space"]
    sc = load_scenario(big_site)
    assert len(sc.space.obstacles) > MAX_OBSTACLES
    assert sc.space.own_obstacles == ()
    # Written back (a dump, the digest, a copy sent to a worker): the reference, no boxes.
    assert len(sc.model_dump()["space"]["obstacles"]) == 0
    assert len(sc.model_dump_json()) < 20_000
    shipped = pickle.loads(pickle.dumps(sc))
    assert shipped.space.obstacles == sc.space.obstacles
    assert scenario_digest(shipped) == scenario_digest(sc)


def test_the_boxes_are_the_maps_blocked_floor(big_site):
    sc = load_scenario(big_site)
    x, y, yaw_deg = sc.space.map.pose
    pose = MapPose(x, y, math.radians(yaw_deg))
    footprints = shapely.union_all(
        [
            box(cx - sx / 2, cy - sy / 2, cx + sx / 2, cy + sy / 2)
            for (cx, cy), (sx, sy, _) in ((ob.center, ob.size) for ob in sc.space.obstacles)
        ]
    )
    # Every tooth's first 0.1 m is a box (within a grid cell), and the band between the
    # teeth's tips is free of boxes.
    for tx in np.arange(0.3, 23.8, 0.25):
        for ty in (0.05, 6.95):
            assert footprints.distance(Point(*pose.map2world(np.array([tx + 0.05, ty])))) < 0.1
    band = Polygon(pose.map2world(np.array([[0.5, 1.7], [23.5, 1.7], [23.5, 5.3], [0.5, 5.3]])))
    assert not footprints.intersects(band)


def test_a_changed_map_is_refused_naming_the_file_and_both_hashes(big_site, tmp_path, capsys):
    image = big_site.parent.parent / "maps" / "map.pgm"
    saved = image.read_bytes()
    written = tomllib.loads(big_site.read_text())["space"]["map"]["sha256"]
    try:
        grid = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
        grid[100, 100] = 0  # one cell more blocked: another floor
        cv2.imwrite(str(image), grid)
        out = tmp_path / "run"
        assert main(["run", str(big_site), "--fidelity", "geometric", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "space.map.sha256" in err
        assert str(big_site) in err
        assert str(image.with_suffix(".yaml")) in err
        assert written in err
        found = re.search(r"has the sha256 ([0-9a-f]{64})", err)
        assert found
        assert found.group(1) != written
        assert not out.exists()
    finally:
        image.write_bytes(saved)


def test_a_missing_map_is_refused_by_name_and_nothing_is_written(big_site, tmp_path, capsys):
    moved = tmp_path / "elsewhere.toml"
    moved.write_text(big_site.read_text())  # the scenario moved without its map
    out = tmp_path / "run"
    assert main(["run", str(moved), "--fidelity", "geometric", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "space.map.file" in err
    assert str(moved) in err
    assert f"the map {tmp_path.parent / 'maps' / 'map.yaml'} does not exist" in err
    assert "'../maps/map.yaml'" in err
    assert not out.exists()


def test_a_robot_in_a_u_shaped_room_is_stopped_by_its_inner_walls():
    # The free floor is a U: two arms joined at the south, a block of wall (the U's
    # tongue) between them. A mesh of the walls would be collided as its convex hull,
    # which fills the room; the boxes are collided as they are.
    from twin.sim.world import build_world

    u_room = box(0.0, 0.0, 8.0, 6.0).difference(box(2.5, 2.0, 5.5, 6.0))
    pose = MapPose(1.25, 4.0, 0.0)  # the parent starts in the west arm
    boxed = boxed_space(FloorMap(free=u_room), pose)
    smoke = load_scenario(Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml")
    space = smoke.space.model_copy(
        update={
            "size": boxed.size,
            "origin": boxed.origin,
            "obstacles": (),
            "floor_patches": (),
        }
    ).with_map_boxes(tuple(map_obstacle(k, b) for k, b in enumerate(boxed.boxes)))
    children = [(5.0, 1.2), (6.2, 1.2)]  # at the far end of the east arm
    robots = smoke.robots.model_copy(
        update={
            "children": tuple(
                c.model_copy(update={"start_xy": xy})
                for c, xy in zip(smoke.robots.children, children, strict=True)
            )
        }
    )
    sc = smoke.model_copy(update={"space": space, "robots": robots})
    world = build_world(sc)
    # Straight east, through the tongue, to the east arm.
    outcome = world.drive_to("parent", (5.5, 0.0), timeout=20.0)
    assert outcome.status == "collision"
    stopped = pose.world2map(outcome.pose[:2])
    radius = 0.3  # the parent's half width: its body stays that far from the tongue
    assert stopped[0] < 2.5 - radius + 0.05
    assert u_room.buffer(-0.2).contains(Point(*stopped))
    # Driven back down its arm and along the base, it reaches the east arm.
    for goal in ((0.0, -3.0), (4.5, -3.0), (5.5, -2.5)):
        assert world.drive_to("parent", goal, timeout=30.0).status in ("reached",), goal
    assert u_room.contains(Point(*pose.world2map(world.robot_pose("parent")[:2])))
