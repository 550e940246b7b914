"""Bad inputs to the LED detector raise ValueError naming the problem and the value."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.detection import (
    DetectionFailure,
    DetectorConfig,
    LedDetection,
    NoiseModel,
    SwitchingSequence,
    detect_leds,
)
from calib.detection.classify import predict_on_line
from calib.detection.noise import estimate_noise

SEQ = SwitchingSequence.one_at_a_time(2)  # 4 frames: dark, LED 0, LED 1, dark
SHAPE = (30, 40)


def frames(dtype=np.uint8, n: int = 4, shape=SHAPE) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.integers(50, 60, (n, *shape)).astype(dtype)


def test_frame_count_must_match_the_pattern() -> None:
    with pytest.raises(ValueError, match="got 3 frames but the switching pattern has 4 rows"):
        detect_leds(frames(n=3), SEQ)
    # A single colour image is not a stack of frames; the message says so.
    with pytest.raises(ValueError, match=r"a single colour image\?"):
        detect_leds(np.zeros((30, 40, 3), np.uint8), SEQ)


def test_frames_of_different_shapes() -> None:
    imgs = list(frames())
    imgs[2] = imgs[2][:, :-1]
    with pytest.raises(
        ValueError, match=r"frame 2 has shape \(30, 39\) but frame 0 has \(30, 40\)"
    ):
        detect_leds(imgs, SEQ)


@pytest.mark.parametrize(
    "shape", [(4, 30), (4, 30, 40, 3, 1), (4, 30, 40, 4), (4, 30, 40, 1)], ids=str
)
def test_wrong_ndim_or_channels(shape) -> None:
    with pytest.raises(ValueError, match=r"\(n_frames, H, W\) or \(n_frames, H, W, 3\), got"):
        detect_leds(np.zeros(shape, np.uint8), SEQ)


def test_non_finite_floats() -> None:
    f = frames(float)
    f[1, 3, 4] = np.nan
    f[3, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"2 NaN or inf value\(s\), first in frame 1"):
        detect_leds(f, SEQ)


def test_empty_images_and_no_frames() -> None:
    with pytest.raises(ValueError, match=r"empty images: shape \(4, 0, 40\)"):
        detect_leds(np.zeros((4, 0, 40), np.uint8), SEQ)
    with pytest.raises(ValueError, match="frames is empty"):
        detect_leds([], SEQ)


@pytest.mark.parametrize("dtype", [bool, complex, object])
def test_frames_of_the_wrong_type(dtype) -> None:
    with pytest.raises(ValueError, match=f"integer or float images, got dtype {np.dtype(dtype)}"):
        detect_leds(np.zeros((4, *SHAPE), dtype), SEQ)


def test_one_dark_frame_needs_a_noise_model() -> None:
    pattern = SEQ.pattern[:-1]
    with pytest.raises(ValueError, match=r"1 dark frame, .* give noise=NoiseModel\(read_dn="):
        detect_leds(frames(n=3), pattern)
    res = detect_leds(frames(n=3), pattern, noise=NoiseModel(read_dn=3.0))
    assert res.failures() == {0: DetectionFailure.NOT_FOUND, 1: DetectionFailure.NOT_FOUND}


def test_bad_noise_and_config_arguments() -> None:
    with pytest.raises(ValueError, match="noise must be a NoiseModel or None, got float"):
        detect_leds(frames(), SEQ, noise=2.0)
    with pytest.raises(ValueError, match="config must be a DetectorConfig, got dict"):
        detect_leds(frames(), SEQ, config={"threshold_sigma": 4})


@pytest.mark.parametrize(
    ("led_line", "message"),
    [
        ([0.3], r"one position per LED, shape \(2,\), got \(1,\)"),
        ([0.3, np.nan], "led_line must be finite"),
        ([0.3, 0.3], "led_line positions must be distinct"),
    ],
)
def test_bad_led_line(led_line, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        detect_leds(frames(), SEQ, led_line=led_line)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("threshold_sigma", 0.0, "threshold_sigma must be a positive number, got 0.0"),
        ("min_snr", math.nan, "min_snr must be a positive number, got nan"),
        ("noise_floor_dn", -1.0, "noise_floor_dn must be a positive number"),
        ("max_area_px", 0, "max_area_px must be a positive integer, got 0"),
        ("max_area_px", 12.5, "max_area_px must be a positive integer, got 12.5"),
        ("dilate_px", -1, r"dilate_px must be 0..10 pixels, got -1"),
        ("on_ratio", 1.0, r"on_ratio must lie in \(0, 1\), got 1.0"),
        ("off_ratio", 0.0, r"off_ratio must lie in \(0, 1\)"),
        ("channel", "infrared", "channel must be one of .* got 'infrared'"),
        ("color_order", "grb", "color_order must be one of"),
        ("saturation_dn", 0.0, "saturation_dn must be None or positive, got 0.0"),
    ],
)
def test_config_validation(field: str, value, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        DetectorConfig(**{field: value})


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"read_dn": 0.0}, "read_dn must be a positive finite number of DN, got 0.0"),
        ({"read_dn": math.inf}, "read_dn must be a positive finite"),
        ({"read_dn": 1.0, "gain_e_per_dn": 0.0}, r"gain_e_per_dn must be positive \(math.inf"),
        ({"read_dn": 1.0, "black_level_dn": math.nan}, "black_level_dn must be finite"),
    ],
)
def test_noise_model_validation(kwargs, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        NoiseModel(**kwargs)


def test_noise_model_values() -> None:
    model = NoiseModel(read_dn=2.0, gain_e_per_dn=10.0, black_level_dn=16.0)
    np.testing.assert_allclose(model.variance([0.0, 16.0, 116.0]), [4.0, 4.0, 14.0])
    np.testing.assert_allclose(NoiseModel(read_dn=3.0).sigma([0.0, 255.0]), [3.0, 3.0])


def test_noise_estimation_inputs() -> None:
    with pytest.raises(ValueError, match=r"k >= 2, got shape \(1, 30, 40\)"):
        estimate_noise(np.zeros((1, *SHAPE)))
    with pytest.raises(ValueError, match="at least 200 usable pixels, got 100"):
        estimate_noise(np.zeros((2, 10, 10)))
    with pytest.raises(ValueError, match="floor_dn must be positive"):
        estimate_noise(np.zeros((2, *SHAPE)), floor_dn=0.0)


def test_a_detection_has_a_position_or_a_failure_never_both() -> None:
    with pytest.raises(ValueError, match="LED 1: exactly one of pixel and failure"):
        LedDetection(1)
    with pytest.raises(ValueError, match="LED 2: exactly one of pixel and failure"):
        LedDetection(2, pixel=np.zeros(2), failure=DetectionFailure.OCCLUDED)


def test_line_prediction_inputs_and_geometry() -> None:
    with pytest.raises(ValueError, match="k >= 3 positions"):
        predict_on_line(np.array([0.0, 1.0]), np.zeros((2, 2)), 2.0)
    # A line imaged in perspective: position s = 10 t / (1 + 0.2 t) along an image line.
    t = np.array([0.0, 1.0, 2.0, 3.0])
    s = 10 * t / (1 + 0.2 * t)
    pixels = np.column_stack([100 + 0.6 * s, 50 + 0.8 * s])
    pred = predict_on_line(t[:3], pixels[:3], 3.0)
    np.testing.assert_allclose(pred.pixel, pixels[3], atol=1e-9)
    assert pred.residual_px < 1e-9
    # Beyond the vanishing point (t = -5) the line is not imaged: no prediction.
    assert predict_on_line(t[:3], pixels[:3], -6.0).pixel is None


def test_float_frames_that_look_normalised_are_noted() -> None:
    f = frames(float) / 255.0
    res = detect_leds(f, SEQ)
    assert any("look normalised to [0, 1]" in m for m in res.messages)
