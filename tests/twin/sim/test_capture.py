"""Camera frames and their ground truth: rendered LEDs land on the true pixels, hidden LEDs
are marked hidden, switching sequences, light level and flicker."""

from __future__ import annotations

import numpy as np
import pytest

from calib.opencv_camera import OpenCVCamera
from twin.scenario.schema import Obstacle
from twin.sim.capture import CameraSimulator
from twin.sim.world import build_world

from .helpers import scenario

ONE_AT_A_TIME = np.array(
    [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, 0]], bool
)


def smoke(**space_changes):
    sc = scenario("smoke")
    if space_changes:
        sc = sc.model_copy(update={"space": sc.space.model_copy(update=space_changes)})
    return sc


def with_camera(sc, **changes):
    cams = tuple(c.model_copy(update=changes) for c in sc.cameras)
    return sc.model_copy(update={"cameras": cams})


def facing(world, camera, xy):
    """Yaw that turns a robot at ``xy`` towards the camera (the LEDs face forward)."""
    p = world.camera(camera).position
    return float(np.arctan2(p[1] - xy[1], p[0] - xy[0]))


def blob_centroid(on, off, near, window=7):
    """Centroid of the positive on-off difference in a window around pixel ``near``."""
    d = np.clip(on.astype(float).mean(axis=2) - off.astype(float).mean(axis=2), 0.0, None)
    u0, v0 = (round(c) for c in near)
    patch = d[v0 - window : v0 + window + 1, u0 - window : u0 + window + 1]
    vv, uu = np.mgrid[v0 - window : v0 + window + 1, u0 - window : u0 + window + 1]
    return np.array([(patch * uu).sum(), (patch * vv).sum()]) / patch.sum(), patch.max()


@pytest.mark.parametrize("lens", ["tsai", "opencv"])
def test_rendered_leds_land_on_their_true_pixels(lens):
    sc = smoke()
    if lens == "tsai":
        sc = with_camera(sc, kappa1=3.0e-6)  # ~20 px at the corners, f = 400 px
    else:
        sc = with_camera(sc, opencv_distortion=(-0.2, 0.05, 0.001, -0.0005))
    world = build_world(sc)
    cam = world.camera("cam1")
    assert isinstance(cam, OpenCVCamera) == (lens == "opencv")
    noiseless = sc.camera("cam1").sensor.model_copy(update={"noise": False, "supersample": 2})
    errors = []
    with CameraSimulator(world) as sim:
        for xy in [(1.5, 0.0), (0.5, -1.8), (2.5, 1.6), (-0.5, 1.2)]:
            world.place("child1", xy, facing(world, "cam1", xy))
            frames = sim.capture_sequence("cam1", "child1", ONE_AT_A_TIME, 0.0, noiseless)
            truth = frames[0].truth("child1")
            np.testing.assert_allclose(
                frames[0].pixels("child1"),
                cam.project(world.marker_points("child1")[1]),
                atol=1e-9,
            )
            for k, t in enumerate(truth):
                if not t.visible or not (8 < t.pixel[0] < 312 and 8 < t.pixel[1] < 232):
                    continue
                c, _ = blob_centroid(frames[k + 1].image, frames[0].image, t.pixel)
                errors.append(c - t.pixel)
    errors = np.array(errors)
    assert len(errors) >= 10
    # Supersampled, noise-free: the rendered centroid is the true pixel to a few
    # hundredths of a pixel, distortion included (without it the errors are pixels).
    assert np.sqrt((errors**2).sum(axis=1).mean()) < 0.05


def test_an_led_behind_an_obstacle_is_marked_hidden_and_is_not_in_the_image():
    crate = Obstacle(name="crate", center=(2.2, 0.0), size=(0.4, 0.8, 1.0))
    world = build_world(smoke(obstacles=(crate,)))
    world.place("child1", (1.5, 0.0), facing(world, "cam1", (1.5, 0.0)))
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("cam1", "child1", ONE_AT_A_TIME, 0.0)
    truth = frames[0].truth("child1")
    assert [t.in_image for t in truth] == [True] * 4
    # Seen from 2.0 m up at 4.5 m, the crate (1.0 m high) hides the two lowest LEDs.
    assert [t.visible_fraction for t in truth] == [0.0, 0.0, 1.0, 1.0]
    for k, t in enumerate(truth):
        _, peak = blob_centroid(frames[k + 1].image, frames[0].image, t.pixel)
        # A lit LED saturates (+150 DN or more over the background); a hidden one leaves
        # only noise (2-3 DN a pixel, 5 sigma ~ 15 DN).
        assert (peak > 150) == t.visible


def test_sequence_switches_the_leds_and_restores_the_world():
    world = build_world(smoke())
    world.place("child1", (1.5, 0.0), facing(world, "cam1", (1.5, 0.0)))
    t0 = world.time
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("cam1", "child1", ONE_AT_A_TIME, frame_interval=0.1)
    np.testing.assert_allclose([f.time - t0 for f in frames], 0.1 * np.arange(6), atol=1e-9)
    for f, row in zip(frames, ONE_AT_A_TIME, strict=True):
        assert [t.lit for t in f.truth("child1")] == list(row)
        assert [t.lit for t in f.truth("child2")] == [False] * 4
        assert f.image.shape == (240, 320, 3)
        assert f.image.dtype == np.uint8
    assert world.sensing.leds_on("child1") == [False] * 4
    assert world.sensing.light_level == 1.0
    with pytest.raises(ValueError, match=r"shape \(n_frames, 4\)"):
        CameraSimulator(world).capture_sequence("cam1", "child1", np.ones((3, 2), bool))


def test_light_level_scales_the_image():
    world = build_world(smoke())
    noiseless = world.scenario.camera("cam1").sensor.model_copy(update={"noise": False})
    with CameraSimulator(world) as sim:
        full = sim.capture("cam1", noiseless).image.astype(float)
        world.sensing.set_light_level(0.5)
        half = sim.capture("cam1", noiseless).image.astype(float)
    lit = (full > 20) & (full < 250)
    ratio = np.median(half[lit] / full[lit])
    assert ratio == pytest.approx(0.5, abs=0.02)
    with pytest.raises(ValueError, match="light level"):
        world.sensing.set_light_level(-0.1)


def test_flicker_and_drift_change_the_light_from_frame_to_frame():
    lighting = scenario("smoke").space.lighting
    world = build_world(smoke(lighting=lighting.model_copy(update={"drift_per_frame": -0.1})))
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("cam1", "child1", ONE_AT_A_TIME[:3], 0.0)
    np.testing.assert_allclose([f.light_level for f in frames], [1.0, 0.9, 0.81])
    world = build_world(smoke(lighting=lighting.model_copy(update={"flicker": 0.1})))
    levels = []
    for _ in range(2):
        with CameraSimulator(world, seed=5) as sim:
            levels.append(
                [f.light_level for f in sim.capture_sequence("cam1", "child1", ONE_AT_A_TIME, 0.0)]
            )
    assert levels[0] == levels[1]  # the same seed flickers the same
    assert 0.02 < np.std(levels[0]) < 0.3


def test_place_puts_a_robot_at_rest_and_resets_its_odometry():
    world = build_world(smoke())
    world.place("child2", (2.0, -1.0), 0.7)
    pose = world.robot_pose("child2")
    np.testing.assert_allclose(pose, [2.0, -1.0, 0.7], atol=5e-3)
    np.testing.assert_allclose(world.driving.odometry["child2"].pose, pose, atol=1e-9)
    world.run(0.5)
    np.testing.assert_allclose(world.robot_pose("child2"), pose, atol=2e-3)


def test_flicker_does_not_depend_on_the_noise_or_on_other_cameras():
    sc = scenario("led_range")
    lighting = sc.space.lighting.model_copy(update={"flicker": 0.05})
    sc = sc.model_copy(update={"space": sc.space.model_copy(update={"lighting": lighting})})
    quiet = sc.camera("near").sensor.model_copy(update={"noise": False})
    runs = []
    for noise, other_first in ((True, False), (False, False), (True, True)):
        world = build_world(sc)
        with CameraSimulator(world, seed=9) as sim:
            if other_first:
                sim.capture("far")
            frames = sim.capture_sequence(
                "near", "child1", ONE_AT_A_TIME, 0.0, None if noise else quiet
            )
        runs.append(([f.light_level for f in frames], frames[0].image))
    assert runs[0][0] == runs[1][0] == runs[2][0]
    np.testing.assert_array_equal(runs[0][1], runs[2][1])  # same noise for "near" too
