"""``twin site`` repairs a plan whose noise-free run drops a visit (another station, shorter
legs, another order), writes the repaired plan, and names what it cannot repair."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.twin.planning.test_site import ORIGIN, write_cameras, write_grid
from twin.cli import main
from twin.planning import repair
from twin.planning.frames import MapPose
from twin.planning.repair import Failed, Fix, TrialRun, repair_plan
from twin.planning.site import SitePlan
from twin.planning.stations import AVOID_RADIUS
from twin.scenario import load_scenario
from twin.scenario.overrides import with_values

DEAD_END = [(0.0, 5.0, 10.0, 5.2)]
"""A wall that makes the room's top a dead-end corridor (y 5.2 to 8 m), open at x > 10 m."""

INTO_THE_DEAD_END = {
    "name": "cam1",
    "position": [9.0, 6.6, 2.0],
    "view_direction": [-1.0, 0.0, -0.45],
    "f": 400.0,
    "cx": 159.5,
    "cy": 119.5,
    "image_size": [320, 240],
}
"""A camera at the corridor's mouth looking down it: its view is the corridor's middle."""

AWAY = re.compile(r"another station for cam1, away from \((-?[\d.]+), (-?[\d.]+)\)")


def _site(tmp_path: Path) -> tuple[Path, Path]:
    return write_grid(tmp_path, DEAD_END), write_cameras(tmp_path, [INTO_THE_DEAD_END])


def test_a_station_the_robots_cannot_reach_is_moved_and_the_repaired_plan_written(
    tmp_path, capsys, monkeypatch
):
    # The map is out of date: something the map does not show stands on the first plan's
    # station (the fault blocks that place in every run), and the parent stops short of
    # it. The repair's station, away from it, calibrates the camera; that plan is the one
    # written.
    real = repair.trial_run
    blocked: list[np.ndarray] = []  # the place, in the map's frame (W moves with the start)

    def pose_of(sc) -> MapPose:
        x, y, yaw = sc.site.map_pose
        return MapPose(x, y, np.radians(yaw))

    def out_of_date(sc):
        if not blocked:
            blocked.append(pose_of(sc).world2map(np.asarray(sc.calibration.visits[0].station)))
        here = pose_of(sc).map2world(blocked[0])
        return real(with_values(sc, {"faults.unreachable": [here.tolist()]}))

    monkeypatch.setattr(repair, "trial_run", out_of_date)
    grid, cams = _site(tmp_path)
    out = tmp_path / "dead_end.toml"
    assert main(["site", str(grid), "--cameras", str(cams), "--out", str(out)]) == 0
    said = " ".join(capsys.readouterr().out.split())
    (line,) = [s for s in said.split("repair: ")[1:] if s.startswith("another station")]
    assert "1 cameras calibrated, 0 visits dropped; kept" in line
    first = np.array([float(v) for v in AWAY.search(line).groups()])
    assert "every camera of the plan is calibrated by the repaired plan" in said
    sc = load_scenario(out)
    (visit,) = sc.calibration.visits
    station = pose_of(sc).world2map(np.asarray(visit.station))
    assert np.linalg.norm(station - first) >= AVOID_RADIUS
    assert np.abs(first - blocked[0]).max() <= 0.005  # the place named, to the cm printed


def test_a_plan_no_repair_mends_is_written_and_the_camera_named_with_why(
    tmp_path, capsys, monkeypatch
):
    # Every station is unreachable (a blocked goal on whatever station a plan has): the
    # repairs tried end with the camera named, the recorded reason and where it failed.
    real = repair.trial_run

    def blocked(sc):
        stations = [list(v.station) for v in sc.calibration.visits]
        return real(with_values(sc, {"faults.unreachable": stations}))

    monkeypatch.setattr(repair, "trial_run", blocked)
    grid, cams = _site(tmp_path)
    out = tmp_path / "blocked.toml"
    args = ["site", str(grid), "--cameras", str(cams), "--out", str(out), "--repairs", "2"]
    assert main(args) == 1
    said = " ".join(capsys.readouterr().out.split())
    tried = said.split("repair: ")[1:]
    assert len(tried) == 2
    assert tried[0].startswith("another station for cam1")
    cause = "cam1 visit 1 (station_unreachable: the parent stopped short) dropped; repair: "
    assert said.count(cause) == 2
    assert tried[1].startswith("shorter legs (2.5 m)")
    assert all("0 cameras calibrated, 1 visits dropped; not better, undone" in t for t in tried)
    assert "2 repairs tried, 0 kept" in said
    assert "does not calibrate every camera after 2 repairs" in said
    found = re.search(
        r"cam1: station_unreachable: the parent stopped short \(the travel to its station "
        r"failed at \((-?[\d.]+), (-?[\d.]+)\) in the map's frame\)",
        said,
    )
    assert found is not None, said
    sc = load_scenario(out)  # the plan is written all the same
    pose = MapPose(sc.site.map_pose[0], sc.site.map_pose[1], np.radians(sc.site.map_pose[2]))
    station = pose.world2map(np.asarray(sc.calibration.visits[0].station))
    np.testing.assert_allclose([float(v) for v in found.groups()], station, atol=0.006)
    # Not the map's origin: the room's coordinates are shifted in the map.
    assert station[0] > ORIGIN[0]


def _plan(order: tuple[str, ...]) -> SitePlan:
    """A plan with only what the repairs read: W at the map's origin, the visits' order."""
    return SitePlan({}, MapPose(), None, {}, order, np.zeros((2, 2)), None)  # type: ignore[arg-type]


def _run(failed: Failed | None) -> TrialRun:
    calibrated = frozenset() if failed else frozenset({"cam1", "cam2"})
    dropped = [{"camera": "cam2"}] if failed else []
    return TrialRun({}, calibrated, 2 - len(dropped), dropped, failed, {})


@pytest.mark.parametrize("fixed_order", [False, True])
def test_a_travel_that_fails_on_the_way_tries_shorter_legs_first(fixed_order):
    # The travel to cam2 fails 12 m before its station: shorter legs, then another station,
    # then legs shorter still, then (unless the user gave the order) other orders; a repair
    # that calibrates more is kept and ends the loop.
    failed = Failed(
        "cam2",
        1,
        "travel",
        "campaign_aborted: no formation",
        np.array([3.0, 0.0]),
        np.array([15.0, 0.0]),
    )
    fixes: list[Fix] = []

    def planner(fix: Fix):
        fixes.append(fix)
        return _plan(("cam1", "cam2")), fix

    def run(fix: Fix) -> TrialRun:
        return _run(None if fix.order == ("cam2", "cam1") else failed)

    repaired = repair_plan(
        planner,
        default_step=5.0,
        fixed_order=fixed_order,
        attempts=10,
        run=run,  # type: ignore[arg-type]
    )
    tried = [(f.step, f.avoid, f.order) for f in fixes[1:]]
    avoid = {"cam2": ((15.0, 0.0),)}
    expected = [(2.5, {}, None), (None, avoid, None), (1.25, {}, None)]
    if not fixed_order:
        expected.append((None, {}, ("cam2", "cam1")))
    assert tried == expected
    assert [a.kept for a in repaired.attempts] == [False] * (len(expected) - 1) + [not fixed_order]
    assert repaired.fix == (fixes[-1] if not fixed_order else Fix())


def test_the_repairs_stop_at_their_bound():
    failed = Failed("cam2", 1, "station", "too_few_points", np.zeros(2), np.zeros(2))
    calls: list[Fix] = []

    def planner(fix: Fix):
        calls.append(fix)
        return _plan(("cam1", "cam2")), fix

    repaired = repair_plan(
        planner, default_step=5.0, fixed_order=False, attempts=2, run=lambda _: _run(failed)
    )
    assert len(repaired.attempts) == 2
    assert len(calls) == 3
    # Data that failed at the station: another station first.
    assert repaired.attempts[0].fix.avoid == {"cam2": ((0.0, 0.0),)}
    assert repaired.fix == Fix()


def test_a_repair_count_out_of_range_is_refused_by_name(tmp_path, capsys):
    grid, cams = _site(tmp_path)
    out = tmp_path / "s.toml"
    with pytest.raises(SystemExit) as exit_:
        main(["site", str(grid), "--cameras", str(cams), "--out", str(out), "--repairs", "101"])
    assert exit_.value.code == 2
    assert "argument --repairs: expected 0 to 100, got 101" in capsys.readouterr().err
    assert not out.exists()


def test_the_commands_bounds_are_the_planners():
    # The command states its defaults without loading the planner: they must agree.
    from twin.cli import site as site_command

    assert (site_command.ATTEMPTS, site_command.SECONDS) == (repair.ATTEMPTS, repair.SECONDS)


def test_a_repair_that_cannot_be_planned_is_counted_and_the_next_tried():
    from twin.planning.floor_map import MapError

    failed = Failed("cam2", 1, "station", "too_few_points", np.zeros(2), np.zeros(2))

    def planner(fix: Fix):
        if fix.avoid:
            raise MapError("map.yaml", "no station 2 m or more from [[0.0, 0.0]] sees 50 %")
        return _plan(("cam1", "cam2")), fix

    repaired = repair_plan(
        planner, default_step=5.0, fixed_order=True, attempts=2, run=lambda _: _run(failed)
    )
    first, second = repaired.attempts
    assert first.run is None
    assert not first.kept
    assert "no station 2 m or more from [[0.0, 0.0]]" in first.error
    assert first.cause == "cam2 visit 1 (too_few_points)"
    assert second.fix.step == 2.5
    assert second.run is not None


def test_a_station_keeps_away_from_the_places_avoided_and_says_so():
    import shapely

    from twin.planning.stations import NoStationError, choose_station

    sc = load_scenario(Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml")
    kwargs = {
        "instrument_z": 0.0,
        "prism_height": 0.3,
        "instrument_range": (1.3, 100.0),
        "need": 0.5,
    }
    floor = shapely.box(-1.5, -2.5, 2.5, 2.5)
    camera = sc.cameras[0].tsai()
    free = choose_station("cam1", camera, sc.space, floor, **kwargs)
    moved = choose_station("cam1", camera, sc.space, floor, avoid=np.array([free.xy]), **kwargs)
    assert np.linalg.norm(moved.xy - free.xy) >= AVOID_RADIUS
    everywhere = np.array([[x, y] for x in (-1.0, 0.5, 2.0) for y in (-2.0, 0.0, 2.0)])
    with pytest.raises(NoStationError, match=r"no station 2 m or more from \[\[-1\.0, -2\.0\]"):
        choose_station("cam1", camera, sc.space, floor, avoid=everywhere, **kwargs)
