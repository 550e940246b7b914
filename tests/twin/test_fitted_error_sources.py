"""The error sources the paper's numbers call for: the prism pointing error, a real camera's
LED centroid error and the children's creep. Each is zero by default, is refused out of
range, and runs at every fidelity with the size it was given."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering before mujoco)
from calib.detection.sequence import SwitchingSequence
from twin.batch.execute import BatchRun
from twin.batch.steps import record_plan
from twin.hal.led_sensing import ImageLedSensor
from twin.hal.readings import LedObservation
from twin.instruments.noise import polar_sigmas
from twin.instruments.total_station import ARCSEC, TotalStationSpec
from twin.montecarlo.sources import isolate
from twin.run.runner import run_scenario
from twin.scenario import ScenarioError, load_scenario, scenario_from_dict
from twin.scenario.overrides import with_values
from twin.sim.rig.creep import CreepingChildren
from twin.sim.rig.leds import RenderLedSensor

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / "scenarios" / "smoke.toml"


def test_every_new_source_is_zero_by_default():
    sc = load_scenario(SMOKE)
    assert sc.noise.total_station.pointing_sigma == 0.0
    assert sc.noise.led_centroid_px == 0.0
    assert sc.noise.child_creep_m == 0.0
    assert all(c.led_centroid_px is None for c in sc.cameras)
    assert sc.projected_led_px(sc.cameras[0].name) == sc.noise.led_detection_px


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("noise", "led_centroid_px", -0.1),
        ("noise", "led_centroid_px", 11.0),
        ("noise", "child_creep_m", -1e-3),
        ("noise", "child_creep_m", 0.1),
        ("noise.total_station", "pointing_sigma", -1e-3),
        ("noise.total_station", "pointing_sigma", 0.05),
    ],
)
def test_a_source_out_of_range_is_refused_by_its_key(section, key, value):
    import tomllib

    raw = tomllib.loads(SMOKE.read_text())
    node = raw
    for part in section.split("."):
        node = node.setdefault(part, {})
    node[key] = value
    with pytest.raises(ScenarioError, match=key):
        scenario_from_dict(raw, SMOKE)


# -- pointing ---------------------------------------------------------------------------------
def test_pointing_adds_its_angle_in_quadrature_and_shrinks_with_distance():
    spec = TotalStationSpec(pointing_sigma=2e-3)
    polar = np.array([[4.0, 1.0, np.pi / 2], [20.0, 1.0, np.pi / 3]])
    s = polar_sigmas(polar, spec)
    a = 5 * ARCSEC
    np.testing.assert_allclose(s[:, 0], [2e-3 + 8e-6, 2e-3 + 40e-6])
    np.testing.assert_allclose(s[0, 1:], [np.hypot(a, 2e-3 / 4.0)] * 2)
    np.testing.assert_allclose(s[1, 1], np.hypot(a, 2e-3 / (20.0 * np.sin(np.pi / 3))))
    np.testing.assert_allclose(s[1, 2], np.hypot(a, 2e-3 / 20.0))
    # Without pointing error the angles are the datasheet's, exactly.
    plain = polar_sigmas(polar, TotalStationSpec())
    assert np.all(plain[:, 1:] == a)


def test_a_point_above_the_instrument_gets_a_finite_pointing_error():
    s = polar_sigmas(np.array([3.0, 0.0, 0.0]), TotalStationSpec(pointing_sigma=1e-3))
    assert np.all(np.isfinite(s))


# -- centroid, render fidelity ------------------------------------------------------------------
def test_the_rendered_detections_get_the_cameras_centroid_error(monkeypatch):
    found = np.array([[100.0, 50.0], [120.0, 60.0], [np.nan, np.nan], [140.0, 70.0]])

    def detected(self, child, sequence):
        return LedObservation(
            camera="cam",
            child=child,
            timestamp=0.0,
            pixels=found,
            sigma_px=np.array([0.05, 0.05, np.nan, 0.05]),
            failures=(None, None, "occluded", None),
            frames=6,
        )

    monkeypatch.setattr(ImageLedSensor, "observe", detected)
    sensor = object.__new__(RenderLedSensor)
    sensor.sim_leds = {"child1": type("Leds", (), {"hidden": frozenset()})()}
    sensor.timings, sensor.hidden_led_rate = {}, 0.0
    sensor.fault_rng = np.random.default_rng(0)
    sensor.centroid_px, sensor.centroid_rng = 0.4, np.random.default_rng(5)
    seq = SwitchingSequence.binary(4)
    errors = np.array([sensor.observe("child1", seq).pixels - found for _ in range(2000)])
    seen = errors[:, [0, 1, 3]].ravel()
    # 12 000 draws: their standard deviation is 0.4 px within 0.7 %; 5 % is 7 of those.
    assert np.std(seen) == pytest.approx(0.4, rel=0.05)
    assert np.all(np.isnan(errors[:, 2]))
    last = sensor.observe("child1", seq)
    np.testing.assert_allclose(last.sigma_px[[0, 1, 3]], np.hypot(0.05, 0.4))
    sensor.centroid_px = 0.0
    state = sensor.centroid_rng.bit_generator.state
    np.testing.assert_array_equal(sensor.observe("child1", seq).pixels, found)
    assert sensor.centroid_rng.bit_generator.state == state  # nothing added, nothing drawn


# -- creep, geometric and render fidelities --------------------------------------------------
class _World:
    def __init__(self):
        self.shifts: list[tuple[str, np.ndarray]] = []

    def shift(self, robot, dxy):
        self.shifts.append((robot, np.asarray(dxy)))


class _Base:
    name = "parent"

    def drive_to(self, goal_xy, goal_yaw=None):
        return "drove"

    def set_pose(self, x, y, yaw):
        pass


def test_the_children_creep_after_each_leg_of_the_parent():
    world = _World()
    base = CreepingChildren(_Base(), world, ["c1", "c2"], 2e-3, np.random.default_rng(1))
    for _ in range(3000):
        assert base.drive_to([1.0, 0.0]) == "drove"
        base.set_pose(1.0, 0.0, 0.0)  # the fix that ends the leg
    robots = [r for r, _ in world.shifts]
    assert robots == ["c1", "c2"] * 3000
    d = np.array([s for _, s in world.shifts])
    # 12 000 draws: the standard deviation is 2 mm within 0.7 %; 4 % is 6 of those.
    assert np.std(d) == pytest.approx(2e-3, rel=0.04)
    assert abs(d.mean()) < 6 * 2e-3 / np.sqrt(d.size)


def test_a_shifted_robot_moves_without_its_odometry_knowing():
    from twin.sim.world import build_world

    world = build_world(load_scenario(SMOKE))
    robot = world.scenario.robots.children[0].name
    before = world.robot_pose(robot).copy()
    odometry = world.driving.odometry[robot].pose.copy()
    world.shift(robot, [3e-3, -2e-3])
    after = world.robot_pose(robot)
    np.testing.assert_allclose(after[:2] - before[:2], [3e-3, -2e-3], atol=1e-9)
    assert after[2] == pytest.approx(before[2])
    np.testing.assert_array_equal(world.driving.odometry[robot].pose, odometry)


# -- at every fidelity ------------------------------------------------------------------------
SOURCES = {
    # The campaign is told of the creep, as the as-built hall tells it: a campaign that
    # takes its children for still rejects their fixes (the test above) and gives up.
    "creep": {"noise.child_creep_m": 3e-3, "campaign.child_creep_m": 3e-3},
    "pointing": {"noise.total_station.pointing_sigma": 3e-3},
    "led_centroid": {"noise.led_centroid_px": 1.0},
}


@pytest.fixture(scope="module")
def smoke_plan():
    return record_plan(load_scenario(SMOKE), "paper")


@pytest.mark.parametrize("source", list(SOURCES))
def test_each_source_alone_moves_the_batch_and_the_geometric_results(source, smoke_plan, tmp_path):
    # Only this source is simulated; the instruments advertise the full noise, as in an
    # error budget (noise-free, the trials recover the camera exactly).
    full = with_values(load_scenario(SMOKE), SOURCES[source])
    sc = isolate(full, source)
    plan = dataclasses.replace(smoke_plan, scenario=full)
    out = BatchRun(plan, list(range(8)), noise=sc.noise).run()
    ((_, v),) = out.calibrations.items()
    assert np.all(v.calibrated)
    assert np.all(v.position_error > 1e-4)  # a tenth of a millimetre at least
    if source == "creep":
        # Creep reaches the camera only through CPS: the parent's pose is off, the LED
        # points of each stop still fit their pixels exactly.
        assert np.all(np.linalg.norm(out.parent_error, axis=1) > 1e-4)
        assert np.all(v.local_pixel < 1e-6)
    else:
        assert np.all(v.local_pixel > 1e-3)
    # Geometric: one run with only this source differs from the noise-free run.
    results = run_scenario(
        sc, tmp_path / "g", fidelity="geometric", seed=4, report=False, advertised_noise=full.noise
    )
    cal = results["calibrations"][0]
    assert cal["truth"]["position_error_mm"] > 0.1
    if source == "creep":
        assert cal["errors"]["local"]["pixel_mean"] < 1e-6
    else:
        assert cal["errors"]["local"]["pixel_mean"] > 1e-3


# -- what the campaign is told: the assembly's survey, the children's creep -------------------
def _creeping_cps(creep_known: float, creep: float, trials: int = 4000, seed: int = 7):
    """One CPS step in ``trials`` trials: two children placed from the origin with 1 mm
    noise, creeping by ``creep`` while the parent drives 5 m, measured again with 1 mm
    noise. Returns the sequence, its solution and the parent's true translation."""
    from calib.rotation import rot_z
    from twin.localization.joint_state import CpsBatch
    from twin.localization.observation import ChildObservationBatch

    rng = np.random.default_rng(seed)
    names = ["c1", "c2"]
    cov = np.tile(1e-6 * np.eye(3), (trials, 1, 1))
    spots = np.tile([[7.5, 0.7, 1.0], [10.0, -0.7, 1.0]], (trials, 1, 1))
    cps = CpsBatch(names, trials, false_alarm_rate=None, child_creep=creep_known)

    def observe(at, yaw, t):
        level = (at - t[:, None]) @ rot_z(yaw) + 1e-3 * rng.standard_normal(at.shape)
        return [ChildObservationBatch(n, level[:, j], cov) for j, n in enumerate(names)]

    cps.children_moved(observe(spots, np.zeros(trials), np.zeros((trials, 3))))
    moved = spots.copy()
    moved[..., :2] += creep * rng.standard_normal((trials, 2, 2))
    t = np.tile([5.0, 0.0, 0.0], (trials, 1))
    solution = cps.parent_moved(observe(moved, np.zeros(trials), t))
    return cps, solution, t


def test_a_campaign_told_of_the_creep_tests_and_weighs_its_fixes_right():
    creep = 2e-3
    told, told_fix, t = _creeping_cps(creep, creep)
    blind, blind_fix, _ = _creeping_cps(0.0, creep)
    # The fix's chi-square has its degrees of freedom as mean when the creep is allowed
    # for: 4000 trials pin the mean of a chi-square with 2 dof within 0.03 (5 sigma 0.16);
    # a campaign that takes its children for still sees about twice that.
    dof = told_fix.dof
    assert np.mean(told_fix.chi2) == pytest.approx(dof, abs=0.16)
    assert np.mean(blind_fix.chi2) > dof + 1.0

    def normalised(cps):
        err = cps.parent.translation - t
        cov = cps.parent.covariance[:, 1:, 1:]
        return np.mean(np.einsum("ti,tij,tj->t", err, np.linalg.inv(cov), err))

    # And its covariance covers the parent's error: the normalised squared error has mean 3
    # (within 0.04 over 4000 trials; 0.25 is 6 of those); the blind one's does not.
    assert normalised(told) == pytest.approx(3.0, abs=0.25)
    assert normalised(blind) > 6.0


def test_the_marker_fit_allows_for_the_surveyed_geometrys_error():
    from twin.instruments.marker import MarkerAssembly
    from twin.instruments.marker_pose import fit_marker_pose

    rng = np.random.default_rng(2)
    survey, shot = 2e-3, 1e-3
    nominal = MarkerAssembly()
    told = MarkerAssembly(survey_sigma=survey)
    cov = np.tile(shot**2 * np.eye(3), (3, 1, 1))
    chi_told, chi_blind = [], []
    for _ in range(3000):
        built = nominal.cubes_body + survey * rng.standard_normal((3, 3))
        measured = built + shot * rng.standard_normal((3, 3))
        chi_told.append(fit_marker_pose(measured, told, cov).chi2)
        chi_blind.append(fit_marker_pose(measured, nominal, cov).chi2)
    # 3 dof: 3000 fits pin the mean within 0.045 (5 sigma 0.23).
    assert np.mean(chi_told) == pytest.approx(3.0, abs=0.23)
    assert np.mean(chi_blind) > 3 * 3.0
    with pytest.raises(ValueError, match="survey_sigma"):
        MarkerAssembly(survey_sigma=-1.0)


def test_the_render_fidelity_runs_with_the_new_sources(tmp_path):
    # The smoke room at the render fidelity with the camera's centroid error, the prism
    # pointing error and the children's creep (the campaign told of it). The rendered
    # detector alone leaves local residuals near 0.1 px; a centroid error of 0.5 px per
    # coordinate gives a mean residual of about 1.25 x 0.5 = 0.63 px over the points. Over
    # 70 points that mean scatters by a few hundredths; over the 36 gathered here (half the
    # stops, so half the rendering) by 1.4 times that, about 0.04 px, so 0.4-0.9 px is more
    # than five of those either side (measured 0.69 px; 0.73 px with 70 points). Without the
    # reference data set (half the rendered points, none of them in the local residuals).
    sc = with_values(
        load_scenario(SMOKE),
        {
            "noise.led_centroid_px": 0.5,
            "noise.child_creep_m": 2e-3,
            "campaign.child_creep_m": 2e-3,
            "noise.total_station.pointing_sigma": 1e-3,
            "campaign.reference_cameras": [],
            "campaign.station_points": 36,
        },
    )
    results = run_scenario(sc, tmp_path, fidelity="render", seed=3, report=False)
    (cal,) = results["calibrations"]
    assert cal["points"] == 36
    assert 0.4 < cal["errors"]["local"]["pixel_mean"] < 0.9
    assert not results["skipped_visits"]


def test_a_failed_fix_leaves_the_creep_uncounted():
    # A fix whose children do not fit (here: one child moved 5 cm) raises and leaves the
    # sequence as it was, its covariance included: a retry adds the creep once, not again.
    from twin.instruments.errors import InconsistentChildrenError
    from twin.localization.observation import ChildObservation
    from twin.localization.sequence import CpsSequence

    cov = 1e-6 * np.eye(3)
    seq = CpsSequence(["c1", "c2"], child_creep=2e-3)
    spots = {"c1": np.array([7.5, 0.7, 1.0]), "c2": np.array([10.0, -0.7, 1.0])}
    seq.children_moved([ChildObservation(c, p, cov) for c, p in spots.items()])
    before = seq.state_covariance
    moved = {"c1": spots["c1"] - [5.0, 0.0, 0.0], "c2": spots["c2"] - [5.0, -0.05, 0.0]}
    for _ in range(3):
        with pytest.raises(InconsistentChildrenError):
            seq.parent_moved([ChildObservation(c, p, cov) for c, p in moved.items()])
        np.testing.assert_array_equal(seq.state_covariance, before)
    moved["c2"] = spots["c2"] - [5.0, 0.0, 0.0]
    seq.parent_moved([ChildObservation(c, p, cov) for c, p in moved.items()])
    _, p = seq.child_position("c1")
    assert p[0, 0] == pytest.approx(before[4, 4] + 4e-6)


def test_creep_comes_once_per_leg_of_the_parent():
    world = _World()
    base = CreepingChildren(_Base(), world, ["c1", "c2"], 2e-3, np.random.default_rng(1))
    base.drive_to([1.0, 0.0])
    base.drive_to([2.0, 0.0])  # round a corner: the same leg
    assert len(world.shifts) == 2
    base.set_pose(2.0, 0.0, 0.0)  # a fix
    base.drive_to([3.0, 0.0])
    assert len(world.shifts) == 4


# -- a camera's own centroid error ---------------------------------------------------------------
def test_a_camera_may_have_its_own_centroid_error():
    from twin.montecarlo.sources import isolate

    hall = with_values(
        load_scenario(ROOT / "scenarios" / "paper_hall.toml"),
        {"noise.led_centroid_px": 0.4, "cameras.cam2.led_centroid_px": 0.7},
    )
    assert hall.led_centroid_px("cam1") == 0.4  # the noise section's
    assert hall.led_centroid_px("cam2") == 0.7  # its own
    assert hall.projected_led_px("cam2") == pytest.approx(np.hypot(0.05, 0.7))
    quiet = hall.without_noise()
    assert [quiet.led_centroid_px(c.name) for c in quiet.cameras] == [0.0, 0.0, 0.0]
    # In an error budget the camera's own error belongs to the centroid source alone.
    centroid, detection = isolate(hall, "led_centroid"), isolate(hall, "led_detection")
    assert centroid.led_centroid_px("cam2") == 0.7
    assert centroid.noise.led_detection_px == 0.0
    assert detection.led_centroid_px("cam2") == 0.0
    assert detection.projected_led_px("cam2") == 0.05
    with pytest.raises(ScenarioError, match="led_centroid_px"):
        with_values(hall, {"cameras.cam2.led_centroid_px": -0.1})


def test_each_fidelity_gives_each_camera_its_own_centroid_error(smoke_plan, tmp_path):
    from twin.sim.rig import build_sim_rig
    from twin.sim.world import build_world

    smoke = with_values(load_scenario(SMOKE), {"cameras.0.led_centroid_px": 0.6})
    cam = smoke.cameras[0].name
    expected = np.hypot(smoke.noise.led_detection_px, 0.6)
    # Geometric: the camera's sensor.
    rig = build_sim_rig(build_world(smoke), "geometric")
    try:
        assert rig.rig.led_sensors[cam].sigma_px == pytest.approx(expected)
    finally:
        rig.close()
    # Batch: the pixels the trials draw, and what the prediction takes the detector for.
    run = BatchRun(dataclasses.replace(smoke_plan, scenario=smoke), [1, 2])
    assert run.led_px[cam] == pytest.approx(expected)
    assert run.advertised_led_px[cam] == pytest.approx(expected)
    # Render: the camera's own error reaches its rendered detections.
    rendered = build_sim_rig(build_world(smoke), "render")
    try:
        assert rendered.rig.led_sensors[cam].centroid_px == 0.6
    finally:
        rendered.close()
