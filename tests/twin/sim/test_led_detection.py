"""LED detection on the twin's rendered images: accuracy against ground truth at the
paper's distances, identification by the switching sequence, and the failures that must be
reported (a person walking by, a light dimming, an LED hidden behind an obstacle).

The images come from :mod:`twin.sim.capture` (lens, sensor); the detector is
:func:`calib.detection.detect_leds`, which knows nothing about the twin.
"""

from __future__ import annotations

import numpy as np
import pytest

from calib.detection import DetectionFailure, SwitchingSequence, detect_leds
from twin.scenario.schema import Obstacle, Person
from twin.sim.capture import CameraSimulator
from twin.sim.placement import stand_for_led
from twin.sim.world import build_world

from .helpers import scenario

LED_HEIGHTS = np.array([0.35, 0.65, 0.95, 1.25])

# (camera, LED index, distance m, image column px): LEDs 3 to 12 m from the camera, over
# the width of the image, each LED of the assembly in turn.
SAMPLES = [
    ("near", 3, 3.0, 60.0),
    ("near", 2, 3.5, 250.0),
    ("near", 1, 4.5, 160.0),
    ("near", 0, 5.5, 90.0),
    ("far", 3, 6.0, 270.0),
    ("far", 2, 7.0, 50.0),
    ("far", 1, 8.0, 200.0),
    ("far", 0, 9.0, 120.0),
    ("far", 1, 10.0, 280.0),
    ("far", 0, 11.0, 40.0),
    ("far", 0, 12.0, 170.0),
]


def clear_of_border(pixel, size, margin=4.0):
    w, h = size
    return margin <= pixel[0] <= w - 1 - margin and margin <= pixel[1] <= h - 1 - margin


def detection_errors(sequence, noise: bool):
    """Errors (px) of every LED that is whole and in view, with its distance, over SAMPLES.

    Also checks on the way that each of them is found and none is mistaken for another.
    """
    sc = scenario("led_range")
    world = build_world(sc)
    marker = sc.marker.assembly()
    errors, distances, sigmas = [], [], []
    with CameraSimulator(world) as sim:
        for camera, led, distance, u in SAMPLES:
            cam = world.camera(camera)
            xy, yaw = stand_for_led(cam, marker.leds_body[led], sc.space.floor_z, distance, u)
            world.place("child1", xy, yaw)
            sensor = sc.camera(camera).sensor.model_copy(update={"noise": noise})
            frames = sim.capture_sequence(camera, "child1", sequence, sensor=sensor)
            found = detect_leds([f.image for f in frames], sequence, led_line=LED_HEIGHTS)
            truth = frames[0].truth("child1")
            assert truth[led].visible
            for k, t in enumerate(truth):
                d = found.leds[k]
                if t.visible and clear_of_border(t.pixel, cam.image_size):
                    assert d.found, f"{camera} {distance} m LED {k}: {d.failure} {d.message}"
                    errors.append(d.pixel - t.pixel)
                    distances.append(t.distance)
                    sigmas.append(d.sigma_px)
                elif d.found:
                    # Found although a sliver is hidden or it is near the border: the spot
                    # is whole enough to pass the partial-occlusion test, so the centroid
                    # can only be slightly off (a tenth hidden moves it 0.2 px).
                    assert np.linalg.norm(d.pixel - t.pixel) < 0.5
    return np.array(errors), np.array(distances), np.array(sigmas)


def rms(errors):
    return float(np.sqrt((errors**2).sum(axis=1).mean()))


def test_noise_free_centroids_are_within_a_tenth_of_a_pixel_at_3_to_12_m():
    errors, distances, _ = detection_errors(SwitchingSequence.one_at_a_time(4), noise=False)
    assert distances.min() < 3.5
    assert distances.max() > 11.5
    assert len(errors) >= 15
    assert rms(errors) <= 0.1


def test_centroids_with_the_default_sensor_noise_are_within_0_3_px():
    errors, distances, _ = detection_errors(SwitchingSequence.binary(4), noise=True)
    assert distances.max() > 11.5
    assert rms(errors) <= 0.3
    # Measured 0.05 px, as without noise: the bright LEDs leave the sensor noise little
    # say. A regression to twice the noise-free limit would pass 0.3; this does not.
    assert rms(errors) <= 0.1


def test_reported_uncertainty_matches_the_scatter_over_repeated_captures():
    # The same LEDs 11 m away (small, 2.8 px across) captured 16 times with fresh sensor
    # noise: the scatter of each LED's position about its mean is what sigma_px predicts.
    # Half exposure, so the LEDs do not saturate (a saturated pixel has no noise left).
    sc = scenario("led_range")
    world = build_world(sc)
    cam = world.camera("far")
    leds = sc.marker.assembly().leds_body
    xy, yaw = stand_for_led(cam, leds[0], sc.space.floor_z, 11.0, 150.0)
    world.place("child1", xy, yaw)
    seq = SwitchingSequence.binary(4)
    sensor = sc.camera("far").sensor.model_copy(update={"exposure": 0.5})
    positions, sigmas = [], []
    with CameraSimulator(world, seed=3) as sim:
        for _ in range(16):
            frames = sim.capture_sequence("far", "child1", seq, 0.0, sensor)
            found = detect_leds([f.image for f in frames], seq)
            assert found.found.all()
            positions.append(found.pixels())
            sigmas.append(found.sigmas())
    positions = np.array(positions)  # (16, 4, 2)
    scatter = positions.std(axis=0, ddof=1)  # (4, 2)
    predicted = np.mean(sigmas, axis=0)  # (4,)
    ratio = scatter / predicted[:, None]
    # Each of the 8 standard deviations from 16 samples is known to about +-18 % (1
    # sigma); their mean to about +-7 %.
    assert 0.75 < ratio.mean() < 1.3
    assert (ratio > 0.45).all()
    assert (ratio < 1.8).all()


def child_in_view(world, camera, distance=5.0, u=160.0):
    sc = world.scenario
    xy, yaw = stand_for_led(
        world.camera(camera), sc.marker.assembly().leds_body[1], sc.space.floor_z, distance, u
    )
    world.place("child1", xy, yaw)
    return xy


@pytest.mark.parametrize(
    ("seq", "ahead", "start_offset", "crosses_leds"),
    [
        # 1.5 m in front of the child, crossing the view beside the LEDs.
        (SwitchingSequence.one_at_a_time(4), 1.5, 1.0, False),
        # 2 m behind the child, passing behind the LED column during the sequence.
        (SwitchingSequence.binary(4), -2.0, 1.75, True),
    ],
    ids=["in_front_one_at_a_time", "behind_binary"],
)
def test_a_person_walking_through_the_view_makes_no_false_led(
    seq, ahead, start_offset, crosses_leds
):
    sc = scenario("led_range")
    world0 = build_world(sc)
    xy = child_in_view(world0, "far", distance=7.0)
    cam = world0.camera("far")
    # A person in a light shirt walking across the view at 2.5 m/s, somewhere else in
    # every frame of the sequence.
    axis = (cam.position[:2] - xy) / np.linalg.norm(cam.position[:2] - xy)
    side = np.array([-axis[1], axis[0]])
    centre = xy + ahead * axis
    walker = Person(
        name="walker",
        waypoints=(tuple(centre - 2.5 * side), tuple(centre + 2.5 * side)),
        speed=2.5,
        start_offset=start_offset,
        shirt_rgb=(0.9, 0.9, 0.9),
    )
    world = build_world(sc.model_copy(update={"people": (walker,)}))
    child_in_view(world, "far", distance=7.0)
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("far", "child1", seq)
    # The person is in view in most frames, each time somewhere else.
    where = np.array([cam.project([[*p, 0.8]])[0] for f in frames for _, p in f.people])
    assert cam.in_image(where).sum() >= 4
    assert np.ptp(where[:, 0]) > 30
    found = detect_leds([f.image for f in frames], seq, led_line=LED_HEIGHTS)
    assert found.changed_fraction > 0.01
    truth = frames[0].truth("child1")
    for d, t in zip(found.leds, truth, strict=True):
        assert t.visible
        if d.found:
            assert np.linalg.norm(d.pixel - t.pixel) < 0.5, f"false LED {d.led}: {d.pixel}"
        else:
            # The LEDs are all in view and whole: only the moving person can have cost
            # one, and that is what must be said.
            assert d.failure == DetectionFailure.SCENE_CHANGED, d.message
    if crosses_leds:
        assert (~found.found).any()
    else:
        assert found.found.all()
        assert found.rejected, "the person should have been seen and rejected"


@pytest.mark.parametrize("bits", [8, 12])
def test_a_dimming_light_makes_no_false_led_and_is_reported(bits):
    sc = scenario("led_range")
    lighting = sc.space.lighting.model_copy(update={"drift_per_frame": -0.08})
    world = build_world(
        sc.model_copy(update={"space": sc.space.model_copy(update={"lighting": lighting})})
    )
    child_in_view(world, "near", distance=4.0)
    seq = SwitchingSequence.binary(4)
    # A 12-bit sensor delivers uint16 frames with the top bits empty: the detector infers
    # the full scale from them.
    sensor = sc.camera("near").sensor.model_copy(update={"bits": bits})
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("near", "child1", seq, sensor=sensor)
    assert frames[0].image.dtype == (np.uint8 if bits == 8 else np.uint16)
    levels = np.array([f.light_level for f in frames])
    assert levels[-1] < 0.7  # the light lost a third of its level during the capture
    found = detect_leds([f.image for f in frames], seq, led_line=LED_HEIGHTS)
    assert found.light_changed
    assert any("light" in m for m in found.messages)
    np.testing.assert_allclose(
        found.frame_gains / found.frame_gains[0], levels / levels[0], rtol=0.03
    )
    truth = frames[0].truth("child1")
    for d, t in zip(found.leds, truth, strict=True):
        if t.visible and clear_of_border(t.pixel, (320, 240)):
            assert d.found, d.message
        if d.found:
            assert np.linalg.norm(d.pixel - t.pixel) < 0.5


@pytest.mark.parametrize(
    ("height", "failure"), [(0.55, DetectionFailure.OCCLUDED), (0.43, DetectionFailure.PARTIAL)]
)
def test_an_led_hidden_behind_an_obstacle_is_reported_occluded_or_partial(height, failure):
    sc = scenario("led_range")
    world0 = build_world(sc)
    xy = child_in_view(world0, "far", distance=7.0)
    cam = world0.camera("far").position[:2]
    # A crate just in front of the child: 0.55 m high, it hides the lowest LED; 0.43 m
    # high, two thirds of it (whose centroid would then be 1.3 px off).
    toward = (cam - xy) / np.linalg.norm(cam - xy)
    yaw = float(np.arctan2(toward[1], toward[0]))
    crate = Obstacle(
        name="crate",
        center=tuple(xy + 0.42 * toward),
        size=(0.3, 0.8, height),
        yaw_deg=float(np.degrees(yaw)),
    )
    space = sc.space.model_copy(update={"obstacles": (crate,)})
    world = build_world(sc.model_copy(update={"space": space}))
    world.place("child1", xy, yaw)
    seq = SwitchingSequence.one_at_a_time(4)
    with CameraSimulator(world) as sim:
        frames = sim.capture_sequence("far", "child1", seq)
    truth = frames[0].truth("child1")
    assert [t.in_image for t in truth] == [True] * 4
    assert [t.visible_fraction for t in truth[1:]] == [1.0, 1.0, 1.0]
    if failure == DetectionFailure.OCCLUDED:
        assert truth[0].visible_fraction == 0.0
    else:
        assert 0.0 < truth[0].visible_fraction < 0.5
    found = detect_leds([f.image for f in frames], seq, led_line=LED_HEIGHTS)
    assert found.leds[0].failure == failure, found.summary()
    assert found.leds[0].pixel is None
    for k in (1, 2, 3):
        assert found.leds[k].found
        assert np.linalg.norm(found.leds[k].pixel - truth[k].pixel) < 0.5
