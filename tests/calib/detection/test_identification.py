"""Identification of the LEDs by their code, rejection of everything else, and the reasons
reported for LEDs that are not found.

The scene is the paper's: a 320 x 240 camera (f = 770 px) 2.5 m high, pitched 20 degrees
down, and a child robot 5 m away whose LEDs (0.35, 0.65, 0.95, 1.25 m high, 4 cm, so 6 px
across) are 40 px apart in the image. Noise: 2 DN read, 10 e-/DN, 8 bits (sigma about
3.7 DN at 100 DN); the LEDs are 80 DN above the background, so each is found at an SNR of
about 60 with sigma_px about 0.03 px.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from calib.detection import (
    DetectionFailure,
    DetectorConfig,
    NoiseModel,
    RejectReason,
    SwitchingSequence,
    detect_leds,
)
from tests.calib.detection.synth import Led, Sensor, background, mast_pixels, render

HEIGHTS = (0.35, 0.65, 0.95, 1.25)
SHAPE = (240, 320)
PIXELS = mast_pixels(HEIGHTS, distance=5.0, lateral=0.3)  # (4, 2), v from 164 up to 40
SEQUENCES = {
    "one_at_a_time": SwitchingSequence.one_at_a_time(4),
    "binary": SwitchingSequence.binary(4),
}
# With sigma_px about 0.03-0.05 px, 0.25 px is more than 5 sigma for every LED here.
TOL_PX = 0.25


@pytest.fixture(params=list(SEQUENCES), ids=list(SEQUENCES))
def seq(request: pytest.FixtureRequest) -> SwitchingSequence:
    return SEQUENCES[request.param]


def leds_at(pixels, diameter: float = 6.0, peak: float = 80.0) -> list[Led | None]:
    return [Led((float(u), float(v)), diameter, peak) for u, v in pixels]


def positions_in(message: str) -> np.ndarray:
    """(k, 2) the pixel positions "(u, v)" written in a message."""
    pairs = re.findall(r"\((-?\d+\.\d), (-?\d+\.\d)\)", message)
    return np.array(pairs, dtype=float).reshape(-1, 2)


def assert_found_at(res, pixels) -> None:
    assert res.found.all(), res.summary()
    err = np.linalg.norm(res.pixels() - np.asarray(pixels), axis=1)
    assert np.all(err < TOL_PX), (err, res.summary())


def test_both_sequences_identify_all_leds(seq: SwitchingSequence) -> None:
    rng = np.random.default_rng(10)
    res = detect_leds(render(seq.pattern, leds_at(PIXELS), rng, shape=SHAPE), seq)
    assert_found_at(res, PIXELS)
    assert res.rejected == ()
    assert res.changed_fraction == 0.0
    assert not res.light_changed
    np.testing.assert_allclose(res.frame_gains, 1.0, atol=0.01)
    for d in res.leds:
        assert 70 < d.peak < 100  # 80 DN less partial coverage, plus noise
        assert 20 <= d.area <= 40  # a 6 px disc covers 28 px
        assert d.snr > 30
        assert 0.01 < d.sigma_px < 0.06
        assert d.message == ""
    assert "LED 3: (" in res.summary()


def test_leds_close_together_are_told_apart(seq: SwitchingSequence) -> None:
    # Four 4 px LEDs whose centres are only 7-8 px apart: their centroid windows overlap,
    # but in each LED's code-matched image the others cancel or are negative.
    pixels = np.array([[100.0, 100.0], [107.3, 100.4], [100.2, 107.6], [107.7, 107.2]])
    rng = np.random.default_rng(11)
    res = detect_leds(render(seq.pattern, leds_at(pixels, 4.0), rng, shape=SHAPE), seq)
    assert_found_at(res, pixels)


def test_frames_as_a_list_and_pattern_as_an_array() -> None:
    seq = SEQUENCES["binary"]
    frames = render(seq.pattern, leds_at(PIXELS), np.random.default_rng(12), shape=SHAPE)
    res = detect_leds(list(frames), seq.pattern.astype(int))
    assert_found_at(res, PIXELS)


def test_moving_blob_person_and_flickering_lamp_make_no_false_led(
    seq: SwitchingSequence,
) -> None:
    rng = np.random.default_rng(13)
    n = seq.n_frames
    # A large bright blob (30 px) somewhere else in every frame, dark ones included.
    extra = [Led((40 + 25 * f, 60 + 10 * f), 30.0, 120.0).image(SHAPE) for f in range(n)]
    # A small lamp flickering on in frames 1 and 4: a code no LED has (in the binary
    # sequence it cancels in every LED's code-matched image).
    lamp = Led((280.0, 200.0), 5.0, 100.0).image(SHAPE)
    for f in (1, 4):
        extra[f] = extra[f] + lamp
    # A person in a light shirt (50 x 130 px, textured) standing in frames 1 and 2: in the
    # binary sequence exactly LED 0's code, so only its size tells it from an LED.
    mask = np.zeros(SHAPE, bool)
    mask[100:230, 60:110] = True
    person = background(SHAPE, rng, low=190.0, high=230.0, texture=10.0)
    cover = [(mask, person) if f in (1, 2) else None for f in range(n)]
    frames = render(seq.pattern, leds_at(PIXELS), rng, shape=SHAPE, extra=extra, cover=cover)
    res = detect_leds(frames, seq, led_line=HEIGHTS)
    assert_found_at(res, PIXELS)
    reasons = {r for c in res.rejected for r in c.reasons}
    assert RejectReason.TOO_LARGE in reasons
    assert RejectReason.CODE_MISMATCH in reasons or RejectReason.SCENE_CHANGED in reasons
    # The blob and the person are rejected where they are, not mistaken for an LED.
    big = [c for c in res.rejected if RejectReason.TOO_LARGE in c.reasons]
    assert any(c.area > 2000 for c in big)  # the person
    assert all(c.area > 400 for c in big)
    assert res.changed_fraction > 0.005  # the blob moved between the two dark frames
    assert any("changed between the dark frames" in m for m in res.messages)
    # Every rejected candidate carries its reasons in words.
    assert all(c.message and len(c.levels) == n for c in res.rejected)


def test_a_compact_transient_in_one_frame() -> None:
    # A small LED-like flash in frame 2 only. The binary sequence needs two lit frames and
    # two off frames: the flash does not follow any code.
    flash = Led((120.5, 150.2), 5.0, 80.0).image(SHAPE)
    binary = SEQUENCES["binary"]
    extra = [flash if f == 2 else None for f in range(binary.n_frames)]
    rng = np.random.default_rng(14)
    res = detect_leds(
        render(binary.pattern, leds_at(PIXELS), rng, shape=SHAPE, extra=extra), binary
    )
    assert_found_at(res, PIXELS)
    flash_rejects = [c for c in res.rejected if abs(c.pixel[0] - 120.5) < 1]
    assert flash_rejects
    assert all(c.reasons == (RejectReason.CODE_MISMATCH,) for c in flash_rejects)
    # One at a time: frame 2 is LED 1's only lit frame, so the flash has LED 1's code.
    # With the LED there too it is reported AMBIGUOUS (never a wrong position); without
    # it, only its size and shape could tell it apart (documented in the sequence module).
    one = SEQUENCES["one_at_a_time"]
    res = detect_leds(render(one.pattern, leds_at(PIXELS), rng, shape=SHAPE, extra=extra), one)
    assert res.leds[1].failure == DetectionFailure.AMBIGUOUS
    assert res.leds[1].pixel is None
    listed = positions_in(res.leds[1].message)
    assert min(np.linalg.norm(listed - [120.5, 150.2], axis=1)) < TOL_PX
    assert min(np.linalg.norm(listed - PIXELS[1], axis=1)) < TOL_PX


def test_a_global_light_change_is_compensated_and_reported(seq: SwitchingSequence) -> None:
    light = np.ones(seq.n_frames)
    light[2:4] = 1.2  # the room light is 20% brighter in two code frames
    rng = np.random.default_rng(15)
    frames = render(seq.pattern, leds_at(PIXELS), rng, shape=SHAPE, light=light)
    res = detect_leds(frames, seq, led_line=HEIGHTS)
    assert_found_at(res, PIXELS)
    assert res.rejected == ()  # no false LED, nothing even close
    # The median of ~20000 ratios, each with ~3% noise, is good to ~3e-4.
    np.testing.assert_allclose(res.frame_gains, light, atol=0.003)
    assert res.light_changed
    assert any("frame 2: light level 1.200" in m and "+20.0%" in m for m in res.messages)
    # Without compensation the whole background differs by 20% in those frames: a huge
    # region where that follows a code, LEDs that are "not off" where it does not. Still
    # no false LED: everything is rejected, with reasons.
    raw = detect_leds(frames, seq, config=DetectorConfig(compensate_gain=False))
    np.testing.assert_array_equal(raw.frame_gains, 1.0)
    assert not raw.light_changed
    for d in raw.leds:
        if d.found:
            assert np.linalg.norm(d.pixel - PIXELS[d.led]) < TOL_PX
    assert raw.rejected


# -- LEDs that are not found ----------------------------------------------------------------
def test_hidden_led_is_occluded(seq: SwitchingSequence) -> None:
    leds = leds_at(PIXELS)
    leds[1] = None
    res = detect_leds(
        render(seq.pattern, leds, np.random.default_rng(16), shape=SHAPE), seq, led_line=HEIGHTS
    )
    d = res.leds[1]
    assert d.failure == DetectionFailure.OCCLUDED
    assert d.pixel is None
    assert not d.found
    # The predicted place is in the message only: the cross-ratio of the mast puts it
    # where it is, to the 0.03-0.05 px of the three found LEDs times the extrapolation.
    assert "inside the image" in d.message
    [predicted] = positions_in(d.message)
    assert np.linalg.norm(predicted - PIXELS[1]) < 0.3
    assert res.found.tolist() == [True, False, True, True]
    assert np.isnan(res.pixels()[1]).all()
    assert res.failures() == {1: DetectionFailure.OCCLUDED}
    # Without led_line there is nothing to tell occluded from out of view.
    res = detect_leds(render(seq.pattern, leds, np.random.default_rng(16), shape=SHAPE), seq)
    assert res.leds[1].failure == DetectionFailure.NOT_FOUND
    assert "nothing found; out of view or hidden" in res.leds[1].message


@pytest.mark.parametrize("hidden", [0.4, 0.8])
def test_a_partly_hidden_led_is_reported_partial_not_biased(
    seq: SwitchingSequence, hidden: float
) -> None:
    # Something in front covers the lower part of LED 1 (10 px across here): the spot is
    # cut, its centroid would move up by about a third of the hidden height.
    leds = leds_at(PIXELS, diameter=10.0)
    u, v = PIXELS[1]
    rows = np.arange(SHAPE[0])[:, None]
    cut_below = v + 5.0 - hidden * 10.0
    mask = (rows > cut_below) & (rows < v + 8) & (np.abs(np.arange(SHAPE[1])[None, :] - u) < 8)
    mask = np.broadcast_to(mask, SHAPE)
    frames = render(seq.pattern, leds, np.random.default_rng(21), shape=SHAPE)
    bg = render(seq.pattern, [None] * 4, np.random.default_rng(21), shape=SHAPE)
    frames = np.where(mask[None], bg, frames)  # the cover hides the LED in every frame
    res = detect_leds(frames, seq, led_line=HEIGHTS)
    d = res.leds[1]
    assert d.failure == DetectionFailure.PARTIAL, res.summary()
    assert d.pixel is None
    assert "partly hidden" in d.message
    for k in (0, 2, 3):
        assert res.leds[k].found
        assert np.linalg.norm(res.leds[k].pixel - PIXELS[k]) < TOL_PX


def test_led_outside_the_image_is_not_in_view(seq: SwitchingSequence) -> None:
    # At 6.6 m the top LED is above the image (v about -5), the others inside.
    pixels = mast_pixels(HEIGHTS, distance=6.6, lateral=0.3)
    assert pixels[3, 1] < -3
    assert pixels[2, 1] > 20
    res = detect_leds(
        render(seq.pattern, leds_at(pixels, 4.7), np.random.default_rng(17), shape=SHAPE),
        seq,
        led_line=HEIGHTS,
    )
    assert res.found.tolist() == [True, True, True, False]
    assert res.leds[3].failure == DetectionFailure.NOT_IN_VIEW
    assert "outside the 320x240 image" in res.leds[3].message
    # Fewer than three found LEDs cannot predict a place.
    far = mast_pixels(HEIGHTS, distance=8.0, lateral=0.3)  # two LEDs above the image
    res = detect_leds(
        render(seq.pattern, leds_at(far, 3.9), np.random.default_rng(17), shape=SHAPE),
        seq,
        led_line=HEIGHTS,
    )
    assert res.failures() == {2: DetectionFailure.NOT_FOUND, 3: DetectionFailure.NOT_FOUND}
    assert "only 2 other LEDs found" in res.leds[3].message


def test_led_cut_by_the_border_is_not_in_view(seq: SwitchingSequence) -> None:
    pixels = PIXELS.copy()
    pixels[3] = (pixels[3][0], 1.0)  # a 6 px disc reaching beyond the top row
    res = detect_leds(
        render(seq.pattern, leds_at(pixels), np.random.default_rng(18), shape=SHAPE),
        seq,
        led_line=HEIGHTS,
    )
    assert res.leds[3].failure == DetectionFailure.NOT_IN_VIEW
    assert "touches the image border" in res.leds[3].message
    [cut] = [c for c in res.rejected if RejectReason.AT_BORDER in c.reasons]
    assert cut.reasons == (RejectReason.AT_BORDER,)
    assert cut.led == 3
    assert res.found[:3].all()


@pytest.mark.parametrize(("name", "peak"), [("one_at_a_time", 11.0), ("binary", 9.0)])
def test_dim_led_is_too_faint(name: str, peak: float) -> None:
    # 9-11 DN on a 6 px disc is 2-2.5 sigma per pixel of the code-matched image: below
    # the 5 sigma threshold, but 8-10 sigma after the 1 px Gaussian smoothing. Over 30
    # noise seeds these brightnesses gave TOO_FAINT in 29-30 (the rest: found).
    seq = SEQUENCES[name]
    leds = leds_at(PIXELS)
    leds[2] = Led(tuple(PIXELS[2]), 6.0, peak)
    res = detect_leds(
        render(seq.pattern, leds, np.random.default_rng(19), shape=SHAPE), seq, led_line=HEIGHTS
    )
    assert res.leds[2].failure == DetectionFailure.TOO_FAINT, res.summary()
    assert "below the detection level" in res.leds[2].message
    assert res.found.sum() == 3


def test_two_matching_candidates_are_ambiguous(seq: SwitchingSequence) -> None:
    copy = Led((60.3, 100.7), 6.0, 80.0).image(SHAPE)  # LED 0's light twice
    extra = [copy if seq.pattern[f, 0] else None for f in range(seq.n_frames)]
    frames = render(
        seq.pattern, leds_at(PIXELS), np.random.default_rng(20), shape=SHAPE, extra=extra
    )
    res = detect_leds(frames, seq, led_line=HEIGHTS)
    d = res.leds[0]
    assert d.failure == DetectionFailure.AMBIGUOUS
    assert d.pixel is None
    assert "2 candidates follow this code" in d.message
    listed = positions_in(d.message)
    assert min(np.linalg.norm(listed - [60.3, 100.7], axis=1)) < TOL_PX
    assert min(np.linalg.norm(listed - PIXELS[0], axis=1)) < TOL_PX
    assert res.found[1:].all()


def test_someone_walking_through_a_dark_frame_at_the_led(seq: SwitchingSequence) -> None:
    # A person covers LED 2's place in the last dark frame only: the LED follows its code
    # in the code frames, but the LED-off reference is not to be trusted there.
    mask = np.zeros(SHAPE, bool)
    u, v = (round(float(x)) for x in PIXELS[2])
    mask[v - 15 : v + 25, u - 12 : u + 12] = True
    cover = [None] * seq.n_frames
    cover[-1] = (mask, np.full(SHAPE, 30.0))
    frames = render(
        seq.pattern, leds_at(PIXELS), np.random.default_rng(21), shape=SHAPE, cover=cover
    )
    res = detect_leds(frames, seq, led_line=HEIGHTS)
    assert res.failures() == {2: DetectionFailure.SCENE_CHANGED}
    assert "scene changed there" in res.leds[2].message
    assert res.changed_fraction == pytest.approx(mask.mean(), rel=0.2)
    [rej] = res.rejected
    assert rej.reasons == (RejectReason.SCENE_CHANGED,)
    assert rej.led == 2
    assert rej.code == seq.code(2)
    assert np.linalg.norm(rej.pixel - PIXELS[2]) < TOL_PX


# -- inputs of other kinds ------------------------------------------------------------------
def test_colour_frames_use_the_chosen_channel() -> None:
    # A red LED on a grey background: strong in the red channel, absent in blue.
    seq = SEQUENCES["binary"]
    rng = np.random.default_rng(22)
    gray = render(seq.pattern, [None] * 4, rng, shape=SHAPE, sensor=Sensor(quantize=False))
    red = render(seq.pattern, leds_at(PIXELS), rng, shape=SHAPE, sensor=Sensor(quantize=False))
    rgb = np.stack([red, gray, gray], axis=-1).clip(0, 255).astype(np.uint8)
    for channel in ("red", "gray", "max"):
        res = detect_leds(rgb, seq, config=DetectorConfig(channel=channel))
        assert_found_at(res, PIXELS)
    assert detect_leds(rgb, seq, config=DetectorConfig(channel="red")).leds[0].snr > (
        detect_leds(rgb, seq).leds[0].snr
    )
    blue = detect_leds(rgb, seq, config=DetectorConfig(channel="blue"))
    assert not blue.found.any()
    # OpenCV's BGR order: red is the last channel.
    bgr = rgb[..., ::-1]
    res = detect_leds(bgr, seq, config=DetectorConfig(channel="red", color_order="bgr"))
    assert_found_at(res, PIXELS)


def test_sixteen_bit_frames_and_a_single_dark_frame_with_a_given_noise_model() -> None:
    pattern = SEQUENCES["one_at_a_time"].pattern[:-1]  # dark, LED 0..3: one dark frame
    rng = np.random.default_rng(23)
    frames = render(pattern, leds_at(PIXELS), rng, shape=SHAPE, sensor=Sensor(quantize=False))
    frames16 = np.round(frames * 256).clip(0, 65535).astype(np.uint16)
    noise = NoiseModel(read_dn=2.0 * 256, gain_e_per_dn=10.0 / 256)
    res = detect_leds(frames16, pattern, noise=noise)
    assert_found_at(res, PIXELS)
    assert res.noise is noise
    assert res.changed_fraction == 0.0  # one dark frame: nothing to compare


def test_saturated_led_is_found_and_noted() -> None:
    seq = SEQUENCES["binary"]
    leds = leds_at(PIXELS)
    leds[0] = Led(tuple(PIXELS[0]), 6.0, 400.0)  # clipped at 255 DN
    rng = np.random.default_rng(24)
    res = detect_leds(render(seq.pattern, leds, rng, shape=SHAPE), seq)
    # A symmetric clipped disc keeps its centre.
    assert_found_at(res, PIXELS)
    assert "saturated" in res.leds[0].message
    assert res.leds[1].message == ""


def test_a_black_frame_is_not_compensated() -> None:
    seq = SEQUENCES["binary"]
    frames = render(seq.pattern, leds_at(PIXELS), np.random.default_rng(25), shape=SHAPE)
    frames[2] = 0
    res = detect_leds(frames, seq)
    np.testing.assert_array_equal(res.frame_gains, 1.0)
    assert any("frame 2 is nearly black" in m for m in res.messages)
    assert not any(d.found and np.linalg.norm(d.pixel - PIXELS[d.led]) > TOL_PX for d in res.leds)
