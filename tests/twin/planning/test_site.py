"""``twin site``: a scenario planned from a map that the twin runs, its stations, tour and
route, the map-to-W transform, and the named errors of bad maps and cameras."""

from __future__ import annotations

import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from shapely.geometry import LineString, Point

from twin.cli import main
from twin.planning.frames import MapPose
from twin.run.runner import run_scenario
from twin.scenario import load_scenario
from twin.scenario.cross_checks import scenario_station_visibility

RESOLUTION = 0.05
ORIGIN = (-3.0, 2.0)
"""Where the grid's lower-left pixel lies in the map frame, m: the map is not W."""


def write_grid(folder: Path, walls: list[tuple[float, float, float, float]]) -> Path:
    """A 14 x 8 m room (0.2 m walls) as a ROS map (PGM + YAML); ``walls`` are extra
    (x0, y0, x1, y1) blocked rectangles in the room's own coordinates, m."""
    w, h = round(14.4 / RESOLUTION), round(8.4 / RESOLUTION)
    image = np.full((h, w), 254, np.uint8)
    blocked = [(-0.2, -0.2, 14.2, 0.0), (-0.2, 8.0, 14.2, 8.2), (-0.2, 0, 0.0, 8), (14, 0, 14.2, 8)]
    for x0, y0, x1, y1 in [*blocked, *walls]:
        c0, c1 = round((x0 + 0.2) / RESOLUTION), round((x1 + 0.2) / RESOLUTION)
        r1, r0 = h - round((y0 + 0.2) / RESOLUTION), h - round((y1 + 0.2) / RESOLUTION)
        image[max(r0, 0) : r1, max(c0, 0) : c1] = 0
    cv2.imwrite(str(folder / "map.pgm"), image)
    meta = {
        "image": "map.pgm",
        "resolution": RESOLUTION,
        "origin": [ORIGIN[0] - 0.2, ORIGIN[1] - 0.2, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta))
    return folder / "map.yaml"


PILLAR = (8.5, 1.0, 9.1, 1.6)

CAMERAS = [
    {
        "name": "cam1",
        "position": [12.0, 4.0, 2.0],
        "view_direction": [-1.0, 0.0, -0.45],
        "f": 400.0,
        "cx": 159.5,
        "cy": 119.5,
        "image_size": [320, 240],
    },
    {
        "name": "cam2",
        "position": [2.0, 7.5, 2.2],
        "view_direction": [0.3, -1.0, -0.5],
        "f": 400.0,
        "cx": 159.5,
        "cy": 119.5,
        "image_size": [320, 240],
    },
]


def write_cameras(folder: Path, cameras: list[dict] = CAMERAS) -> Path:
    """The cameras in the map frame (the room's coordinates shifted by ORIGIN)."""
    moved = []
    for cam in cameras:
        c = dict(cam)
        x, y, z = cam["position"]
        c["position"] = [x + ORIGIN[0], y + ORIGIN[1], z]
        moved.append(c)
    path = folder / "cameras.yaml"
    path.write_text(yaml.safe_dump(moved))
    return path


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("site")
    grid = write_grid(folder, [PILLAR])
    cams = write_cameras(folder)
    out = folder / "room.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 0
    return folder, out


def test_the_planned_scenario_calibrates_every_camera_in_the_twin(site, tmp_path):
    folder, out = site
    sc = load_scenario(out)
    assert (folder / "room.plan.png").stat().st_size > 10_000
    assert sc.site is not None
    assert sc.site.map == "map.yaml"
    # Every station sees its camera's view as the validation demands; the route starts at
    # the parent's start (W's origin).
    for visit in sc.calibration.visits:
        seen = scenario_station_visibility(sc, visit.camera, visit.station)
        assert seen >= sc.calibration.min_visible_fraction
    assert sc.route.waypoints[0] == (0.0, 0.0)
    results = run_scenario(sc, tmp_path, fidelity="geometric", report=False, cameras=False)
    assert sorted(c["camera"] for c in results["calibrations"]) == ["cam1", "cam2"]
    assert not results["skipped_visits"]
    assert all(c["truth"]["position_error_mm"] < 50.0 for c in results["calibrations"])


def test_the_scenario_keeps_the_map_to_world_transform(site):
    _, out = site
    sc = load_scenario(out)
    x, y, yaw_deg = sc.site.map_pose
    pose = MapPose(x, y, math.radians(yaw_deg))
    for cam, given in zip(sc.cameras, CAMERAS, strict=True):
        in_map = pose.world2map(np.asarray(cam.position[:2]))
        expected = np.add(given["position"][:2], ORIGIN)
        np.testing.assert_allclose(in_map, expected, atol=1e-9)
        # Heights: above the floor in the cameras file, in W the floor is at floor_z.
        assert cam.position[2] == pytest.approx(sc.space.floor_z + given["position"][2])
    # The pillar is a box of the scenario where the map has it (within the grid's cell).
    pillar_w = pose.map2world(
        np.add([(PILLAR[0] + PILLAR[2]) / 2, (PILLAR[1] + PILLAR[3]) / 2], ORIGIN)
    )
    centres = np.array([ob.center for ob in sc.space.obstacles])
    nearest = sc.space.obstacles[int(np.argmin(np.linalg.norm(centres - pillar_w, axis=1)))]
    assert np.linalg.norm(np.subtract(nearest.center, pillar_w)) < 0.1
    assert nearest.size[0] == pytest.approx(0.6, abs=0.11)


def test_a_given_order_and_start_are_kept_and_the_route_returns(tmp_path):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    out = tmp_path / "given.toml"
    start = [str(3.0 + ORIGIN[0]), str(4.0 + ORIGIN[1]), "90"]
    code = main(
        [
            "site",
            str(grid),
            "--cameras",
            str(cams),
            "--out",
            str(out),
            "--no-predict",
            "--visits",
            "cam1,cam2,cam1",
            "--return-to-start",
            "--start",
            *start,
        ]
    )
    assert code == 0
    sc = load_scenario(out)
    assert [v.camera for v in sc.calibration.visits] == ["cam1", "cam2", "cam1"]
    assert sc.route.waypoints[-1] == pytest.approx((0.0, 0.0), abs=1e-9)
    assert sc.route.return_to_start  # the campaign drives back, not only the route
    # A prism near the start closes the loop: in plain sight of the start, off the route.
    (prism,) = sc.control_points
    xy = np.asarray(prism.position[:2])
    assert 1.0 <= np.linalg.norm(xy) <= 2.5
    assert prism.position[2] == 0.0
    assert LineString(sc.route.waypoints).distance(Point(*xy)) >= 0.8
    assert sc.site.map_pose == pytest.approx((0.0, 6.0, 90.0))


def test_a_site_may_plan_its_data_points_for_accuracy(tmp_path):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    out = tmp_path / "accurate.toml"
    args = ["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict"]
    assert main([*args, "--data-stops", "accuracy"]) == 0
    sc = load_scenario(out)
    assert sc.campaign.data_stops == "accuracy"
    results = run_scenario(sc, tmp_path / "run", fidelity="geometric", report=False, cameras=False)
    assert sorted(c["camera"] for c in results["calibrations"]) == ["cam1", "cam2"]


def test_bad_maps_and_cameras_are_named_and_nothing_is_written(tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    out = tmp_path / "bad.toml"
    outside = [dict(CAMERAS[0], position=[40.0, 4.0, 2.0])]
    cams = write_cameras(tmp_path, outside)
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 2
    assert "camera 'cam1' at [37.0, 6.0] lies outside the map" in capsys.readouterr().out
    corrupt = tmp_path / "corrupt.dxf"
    corrupt.write_bytes(b"\x00\x01 not a drawing")
    assert main(["site", str(corrupt), "--cameras", str(cams), "--out", str(out)]) == 2
    assert "corrupt.dxf" in capsys.readouterr().out
    missing = tmp_path / "cams_missing_key.yaml"
    missing.write_text(yaml.safe_dump([{"name": "cam1", "position": [1, 1, 2]}]))
    assert main(["site", str(grid), "--cameras", str(missing), "--out", str(out)]) == 2
    assert "the key 'view_direction' is missing" in capsys.readouterr().out
    assert not out.exists()


def scenario_as_map(path: Path, folder: Path) -> tuple[Path, Path]:
    """A hand-written scenario's floor as a ROS map (5 cm cells) and its cameras as a
    cameras file: what a user with a map of the paper's hall would have."""
    from twin.scenario.geometry import inside_obstacles, inside_space

    sc = load_scenario(path)
    (x0, x1), (y0, y1) = sc.space.x_range, sc.space.y_range
    x0, y0, x1, y1 = x0 - 0.3, y0 - 0.3, x1 + 0.3, y1 + 0.3
    w, h = math.ceil((x1 - x0) / RESOLUTION), math.ceil((y1 - y0) / RESOLUTION)
    xs = x0 + (np.arange(w) + 0.5) * RESOLUTION
    ys = y0 + (np.arange(h) + 0.5) * RESOLUTION
    gx, gy = np.meshgrid(xs, ys[::-1])
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    free = inside_space(sc.space, pts) & ~inside_obstacles(sc.space.obstacles, pts).any(axis=0)
    cv2.imwrite(str(folder / "map.pgm"), np.where(free, 254, 0).astype(np.uint8).reshape(h, w))
    meta = {
        "image": "map.pgm",
        "resolution": RESOLUTION,
        "origin": [float(x0), float(y0), 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta))
    cams = [
        {
            "name": c.name,
            "position": [*c.position[:2], c.position[2] - sc.space.floor_z],
            "view_direction": list(c.view_direction),
            "f": c.f,
            "cx": c.cx,
            "cy": c.cy,
            "kappa1": c.kappa1,
            "image_size": list(c.image_size),
        }
        for c in sc.cameras
    ]
    (folder / "cameras.yaml").write_text(yaml.safe_dump(cams))
    return folder / "map.yaml", folder / "cameras.yaml"


def test_the_paper_hall_planned_from_a_map_of_it_calibrates_its_cameras(tmp_path):
    root = Path(__file__).resolve().parents[3]
    grid, cams = scenario_as_map(root / "scenarios" / "paper_hall.toml", tmp_path)
    out = tmp_path / "hall.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--no-predict"]) == 0
    sc = load_scenario(out)
    assert sorted(v.camera for v in sc.calibration.visits) == ["cam1", "cam2", "cam3"]
    results = run_scenario(sc, tmp_path / "run", fidelity="geometric", report=False, cameras=False)
    assert sorted(c["camera"] for c in results["calibrations"]) == ["cam1", "cam2", "cam3"]
    # The shortest tour over the three stations, started before the first: shorter than
    # the paper's 85 m route, which also goes back to cameras 2 and 1.
    assert results["distance_travelled_m"] < 60.0


def test_the_environment_runs_on_a_planned_site(site):
    import gymnasium as gym

    import twin.envs  # noqa: F401  (registers the environment)
    from twin.envs.comparison import play_episode

    _, out = site
    env = gym.make("camnet/CpsCampaign-v0", scenario=str(out))
    try:
        steps, info = play_episode(env.unwrapped, "paper", seed=0)
    finally:
        env.close()
    assert steps > 0
    # The paper's policy in the environment calibrates both cameras of the planned site.
    assert sorted(info["camera_errors_mm"]) == ["cam1", "cam2"]


def test_the_shipped_hospital_floor_calibrates_all_its_cameras(tmp_path):
    root = Path(__file__).resolve().parents[3]
    from twin.planning.sample_floor import write_floor

    # The shipped map and cameras are what the generator makes.
    write_floor(tmp_path / "floor", 30)
    shipped = root / "scenarios" / "hospital_floor"
    assert (tmp_path / "floor" / "cameras.yaml").read_text() == (
        shipped / "cameras.yaml"
    ).read_text()
    made = cv2.imread(str(tmp_path / "floor" / "map.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(made, cv2.imread(str(shipped / "map.png"), cv2.IMREAD_UNCHANGED))
    sc = load_scenario(root / "scenarios" / "hospital_floor.toml")
    assert len(sc.cameras) == 30
    route = np.asarray(sc.route.waypoints)
    assert np.sum(np.linalg.norm(np.diff(route, axis=0), axis=1)) >= 600.0
    results = run_scenario(sc, tmp_path / "run", fidelity="geometric", report=False, cameras=False)
    assert len(results["calibrations"]) == 30
    assert not results["skipped_visits"]


def test_a_camera_the_plans_run_does_not_calibrate_is_named_with_why(tmp_path):
    # The station cannot be reached (an unreachable goal on it): the geometric run that
    # predicts the errors calibrates nothing, and says why for the camera.
    from twin.planning.repair import trial_run
    from twin.scenario.overrides import with_values

    smoke = load_scenario(Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml")
    blocked = with_values(smoke, {"faults.unreachable": [[0.5, 0.0]]})
    run = trial_run(blocked)
    assert run.predicted_mm == {}
    assert list(run.missed) == ["cam1"]
    assert run.missed["cam1"].startswith("station_unreachable")
    assert trial_run(smoke).missed == {}


def test_a_start_near_a_wall_keeps_the_route_off_the_corners(tmp_path):
    # The generated three-camera floor: the start stands 1 m from a wall, so no route 1.5 m
    # clear leaves it. A route at the parent's own clearance grazed a corner where no
    # formation kept its lines of sight (the campaign aborted before cam3); the route 1 m
    # clear calibrates every camera.
    from twin.planning.maps import load_map
    from twin.planning.repair import trial_run
    from twin.planning.sample_floor import write_floor
    from twin.planning.site import plan_site, read_cameras
    from twin.scenario.loader import scenario_from_dict

    map_yaml, cameras = write_floor(tmp_path / "floor", 3)
    plan = plan_site(load_map(map_yaml), read_cameras(cameras))
    run = trial_run(scenario_from_dict(plan.scenario))
    assert run.missed == {}
    assert sorted(run.predicted_mm) == ["cam1", "cam2", "cam3"]


def test_the_data_stops_from_a_station_are_planned_once(tmp_path, monkeypatch):
    # The stations are chosen before the start, then each is checked from the start's side:
    # the check reads the stops the search planned from the station, not planned again.
    import twin.planning.site as site_module
    import twin.planning.site_stations as stations_module
    from twin.planning.maps import load_map
    from twin.planning.sample_floor import write_floor

    planned = []
    plan_stops = stations_module.partial_view_stops

    def counted(space, assembly, reach, camera, xy, *rest):
        planned.append((camera.world2cam_t.tobytes(), np.asarray(xy).tobytes()))
        return plan_stops(space, assembly, reach, camera, xy, *rest)

    monkeypatch.setattr(stations_module, "partial_view_stops", counted)
    map_yaml, cameras = write_floor(tmp_path / "floor", 3)
    plan = site_module.plan_site(load_map(map_yaml), site_module.read_cameras(cameras))
    assert sorted(plan.stations) == ["cam1", "cam2", "cam3"]
    assert len(planned) >= 3
    assert len(set(planned)) == len(planned)


def test_a_bad_camera_value_names_the_cameras_file_the_camera_and_the_key(tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    out = tmp_path / "bad.toml"
    cams = write_cameras(tmp_path, [CAMERAS[0], dict(CAMERAS[1], f=math.nan)])
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 2
    said = capsys.readouterr().out
    assert (
        f"{cams}: camera 1 ('cam2'): f: not a finite number (got nan); expected a number in "
        "[1, 100000]"
    ) in " ".join(said.split())
    assert "<dict>" not in said
    cams.write_text(yaml.safe_dump([dict(CAMERAS[0], position=[1.0, "2", 2.0])]))
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert "camera 0 ('cam1'): position: expected 3 finite numbers" in said
    assert not out.exists()


@pytest.mark.parametrize("start", [None, ["3", "4", "30"]])
def test_a_camera_inside_a_pillar_is_named_in_the_maps_frame(tmp_path, capsys, start):
    grid = write_grid(tmp_path, [PILLAR])
    out = tmp_path / "bad.toml"
    # The pillar's middle, 2 m up: the pillar reaches the ceiling.
    inside = [dict(CAMERAS[0], position=[8.8, 1.3, 2.0]), CAMERAS[1]]
    cams = write_cameras(tmp_path, inside)
    more = [] if start is None else ["--start", *start]
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out), *more]) == 2
    said = " ".join(capsys.readouterr().out.split())
    x0, y0, x1, y1 = (v + o for v, o in zip(PILLAR, ORIGIN * 2, strict=True))
    assert (
        "camera 'cam1' at (5.80, 3.30), 2.00 m above the floor, stands inside the map's "
        f"obstacle 'occupied' (x {x0:.2f} to {x1:.2f}, y {y0:.2f} to {y1:.2f}, up to the "
        "ceiling; the map's frame, m)"
    ) in said
    assert "map_" not in said
    assert not out.exists()


def test_a_camera_over_floor_the_map_does_not_show_is_named(tmp_path, capsys):
    grid = write_grid(tmp_path, [])
    image = cv2.imread(str(tmp_path / "map.pgm"), cv2.IMREAD_UNCHANGED)
    # An unknown patch (neither free nor occupied) at x 9 to 10, y 3 to 4 of the room.
    h = image.shape[0]
    rows = slice(h - round(4.2 / RESOLUTION), h - round(3.2 / RESOLUTION))
    image[rows, round(9.2 / RESOLUTION) : round(10.2 / RESOLUTION)] = 205
    cv2.imwrite(str(tmp_path / "map.pgm"), image)
    cams = write_cameras(tmp_path, [dict(CAMERAS[0], position=[9.5, 3.5, 2.0]), CAMERAS[1]])
    out = tmp_path / "bad.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert "camera 'cam1' at (6.50, 5.50), 2.00 m above the floor, stands inside the map's " in said
    # The patch as the box it is laid as: its edges within a cell of the grid (0.1 m).
    found = re.search(r"blocked floor \(x (\S+) to (\S+), y (\S+) to (\S+), 3.00 m high", said)
    assert found, said
    bounds = [float(v.rstrip(",")) for v in found.groups()]
    assert bounds == pytest.approx([6.0, 7.0, 5.0, 6.0], abs=0.1)
    assert not out.exists()


@pytest.mark.parametrize("visits", ["", ",", " , ,"])
def test_a_visit_order_without_a_camera_is_refused_by_name(visits, tmp_path, capsys):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    out = tmp_path / "site.toml"
    with pytest.raises(SystemExit) as exit_:
        main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--visits", visits])
    assert exit_.value.code == 2
    said = capsys.readouterr().err
    assert "argument --visits: expected camera names separated by commas" in said
    assert repr(visits) in said
    assert not out.exists()


def test_empty_entries_of_a_visit_order_are_left_out():
    from twin.cli.site import visit_order

    assert visit_order(" cam1, ,cam2,cam1,") == ["cam1", "cam2", "cam1"]


@pytest.mark.parametrize(
    ("out", "expected"),
    [
        ("a_file/site.toml", "--out a_file/site.toml: lies under the file a_file"),
        ("folder", "--out folder: is a folder; expected the name of a file"),
        ("site.toml", "--out's figure site.plan.png: is a folder"),
    ],
)
def test_an_output_that_cannot_be_written_is_refused_before_planning(
    out, expected, tmp_path, monkeypatch, capsys
):
    grid = write_grid(tmp_path, [PILLAR])
    cams = write_cameras(tmp_path)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("the user's")
    (tmp_path / "folder").mkdir()
    (tmp_path / "site.plan.png").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["site", str(grid), "--cameras", str(cams), "--out", out, "--no-predict"]) == 2
    assert expected in " ".join(capsys.readouterr().err.split())
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("resolution", ["1e-320", "1e-9", "0.009", "1.5", "1e308", "0", "nan"])
def test_a_grid_out_of_range_is_refused_with_the_range(resolution, tmp_path, capsys):
    out = tmp_path / "site.toml"
    argv = ["site", str(tmp_path / "map.yaml"), "--cameras", str(tmp_path / "c.yaml")]
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--out", str(out), "--resolution", resolution])
    assert exit_.value.code == 2
    said = capsys.readouterr().err
    assert "argument --resolution: expected" in said
    if resolution != "nan":
        assert "expected 0.01 to 1 m" in said
    assert not out.exists()
