"""Sub-pixel accuracy of the LED detector on synthetic frames with a known truth.

Spots are discs of 2.5-10 px (an LED of 4 cm at 12 m to 3 m with f = 770 px) with exact
partial-pixel coverage, on a textured background; the noise is Poisson shot noise with
10 e-/DN plus 2 DN of read noise, quantised to 8 bits (sigma about 3.7 DN at 100 DN).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.detection import DetectorConfig, NoiseModel, SwitchingSequence, detect_leds
from calib.detection.blobs import centroid, rectified_variance
from calib.detection.noise import estimate_noise
from tests.calib.detection.synth import (
    NOISE_FREE,
    NOISE_FREE_8BIT,
    Led,
    Sensor,
    background,
    render,
    sampled_centroid,
)

SHAPE = (40, 160)  # a strip with four LEDs 40 px apart: small and fast
SEQ = SwitchingSequence.binary(4)
DIAMETERS = (2.5, 4.0, 6.0, 10.0)


def _scene(rng: np.random.Generator, diameter: float, peak: float) -> list[Led]:
    """Four LEDs at random sub-pixel positions along the strip."""
    return [
        Led((20 + 40 * i + rng.uniform(-0.5, 0.5), 20 + rng.uniform(-0.5, 0.5)), diameter, peak)
        for i in range(4)
    ]


def _errors(sensor: Sensor, diameter: float, peak: float, trials: int, seed: int):
    """Detector errors against the disc centres and against the sampled spots' centroids."""
    rng = np.random.default_rng(seed)
    to_centre, to_sampled, sigmas = [], [], []
    for _ in range(trials):
        leds = _scene(rng, diameter, peak)
        res = detect_leds(render(SEQ.pattern, leds, rng, shape=SHAPE, sensor=sensor), SEQ)
        assert res.found.all(), res.summary()
        centres = np.array([led.center for led in leds])
        sampled = np.array([sampled_centroid(led.image(SHAPE)) for led in leds])
        to_centre.append(res.pixels() - centres)
        to_sampled.append(res.pixels() - sampled)
        sigmas.append(res.sigmas())
    return np.concatenate(to_centre), np.concatenate(to_sampled), np.concatenate(sigmas)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


@pytest.mark.parametrize("diameter", DIAMETERS)
def test_noise_free_centroids(diameter: float) -> None:
    # Float frames: the detector reproduces the centroid of the sampled spot exactly; what
    # remains against the disc centre is the sampling ("pixel locking") of a small disc,
    # measured 0.012 px RMS for 2.5 px and 0.002 px for 10 px.
    to_centre, to_sampled, _ = _errors(NOISE_FREE, diameter, 80.0, 3, seed=1)
    assert _rms(to_sampled) < 1e-6
    assert _rms(to_centre) <= 0.05
    # 8-bit quantisation adds at most 0.5 DN per pixel to every frame: measured 0.003 px.
    to_centre, to_sampled, _ = _errors(NOISE_FREE_8BIT, diameter, 80.0, 3, seed=2)
    assert _rms(to_sampled) <= 0.01
    assert _rms(to_centre) <= 0.05


@pytest.mark.parametrize("diameter", DIAMETERS)
def test_noisy_centroids(diameter: float) -> None:
    # A dim LED, 30 DN above a background of 40-170 DN: measured RMS 0.12 px (2.5 px disc)
    # down to 0.06 px (10 px disc), well inside 0.3 px.
    to_centre, _, sigmas = _errors(Sensor(), diameter, 30.0, 6, seed=3)
    assert _rms(to_centre) <= 0.3
    assert np.all(sigmas < 0.3)


def test_predicted_sigma_matches_the_scatter() -> None:
    """sigma_px from the noise model against the scatter of repeated noisy sequences."""
    rng = np.random.default_rng(4)
    bg = background(SHAPE, rng)
    leds = [
        Led((20.3, 20.2), 2.5, 30.0),
        Led((60.1, 19.7), 4.0, 80.0),
        Led((99.6, 20.4), 6.0, 30.0),
        Led((140.4, 19.9), 10.0, 30.0),
    ]
    noise = NoiseModel(read_dn=np.sqrt(2.0**2 + 1 / 12), gain_e_per_dn=10.0)
    trials = 100
    pixels, sigmas = [], []
    for _ in range(trials):
        frames = render(SEQ.pattern, leds, rng, shape=SHAPE, bg=bg)
        # The LEDs here differ in size on purpose, so the test that reports a spot much
        # smaller than its neighbours as partly hidden is switched off.
        res = detect_leds(frames, SEQ, noise=noise, config=DetectorConfig(partial_area_ratio=0.0))
        assert res.found.all(), res.summary()
        pixels.append(res.pixels())
        sigmas.append(res.sigmas())
    pixels, sigmas = np.array(pixels), np.array(sigmas)  # (trials, 4, 2), (trials, 4)
    # Each coordinate's deviation from its mean, in units of its predicted sigma.
    z = (pixels - pixels.mean(axis=0)) / sigmas[:, :, None]
    n = z.size - 8  # samples less the 8 fitted means
    ratio = float(np.sqrt((z**2).sum() / n))
    # The estimated standard deviation of n Gaussian samples scatters by 1 / sqrt(2 n)
    # (0.025 here); allow 4 of those, and 8% for the model: it linearises the centroid for
    # a fixed window, while the window (the noisy threshold contour, dilated) moves a
    # little too. Over 400 trials the scatter was 0-6% above the prediction per spot.
    assert abs(ratio - 1.0) <= 4 / np.sqrt(2 * n) + 0.08, ratio
    # Bias (the positive-part weights pull noise toward the window centre) stays small.
    truth = np.array([sampled_centroid(led.image(SHAPE)) for led in leds])
    assert np.all(np.abs(pixels.mean(axis=0) - truth) < 0.08)


@settings(max_examples=25, deadline=None)
@given(
    u=st.floats(10.0, 11.0),
    v=st.floats(12.0, 13.0),
    sigma=st.floats(0.7, 2.0),
)
def test_symmetric_spot_centroid_is_its_centre(u: float, v: float, sigma: float) -> None:
    # A pixel-integrated Gaussian sampled on a grid has its centroid at its centre up to
    # aliasing of order exp(-2 pi^2 sigma^2) (below 1e-4 px for sigma >= 0.7).
    seq = SwitchingSequence.one_at_a_time(1)
    led = Led((u, v), peak=200.0, gauss_sigma=sigma)
    spot = led.image((26, 24))
    c, _ = centroid(spot, np.ones(spot.shape, bool))
    np.testing.assert_allclose(c, [u, v], atol=2e-4)
    # Through the detector the window is the 3.5 DN contour (5 sigma of the 0.5 DN floor)
    # dilated by 2 px, not exactly symmetric on the grid: the wings it leaves out hold
    # under 1e-3 of the flux for sigma <= 2 and move the centroid by less than 1e-3 px.
    frames = render(seq.pattern, [led], np.random.default_rng(0), shape=(26, 24), sensor=NOISE_FREE)
    res = detect_leds(frames, seq)
    np.testing.assert_allclose(res.leds[0].pixel, [u, v], atol=1e-3)


def test_rectified_variance_limits() -> None:
    var = np.full(3, 4.0)
    out = rectified_variance(np.array([-20.0, 0.0, 20.0]), var)
    np.testing.assert_allclose(out, [0.0, 4.0 * (0.5 - 1 / (2 * np.pi)), 4.0], atol=1e-9)


def test_noise_is_estimated_from_the_dark_frames() -> None:
    rng = np.random.default_rng(5)
    bg = background((120, 160), rng, low=20.0, high=220.0)
    frames = np.stack([Sensor().expose(bg, rng) for _ in range(2)]).astype(float)
    est = estimate_noise(frames)
    # 19200 pixels in 16 bins: each bin's variance is good to ~3%, the fitted line better.
    # Quantisation adds 1/12 DN^2 to the read noise.
    assert est.read_dn == pytest.approx(np.sqrt(4 + 1 / 12), rel=0.15)
    assert est.gain_e_per_dn == pytest.approx(10.0, rel=0.15)
    # Noise-free images get the floor, and a flat scene only a constant.
    assert estimate_noise(np.stack([bg, bg])).read_dn == 0.5
    flat = np.full((2, 40, 40), 100.0) + rng.normal(0, 3.0, (2, 40, 40))
    est = estimate_noise(flat)
    assert est.gain_e_per_dn == np.inf
    assert est.read_dn == pytest.approx(3.0, rel=0.1)


def test_noise_free_float_frames_need_no_noise_model() -> None:
    # Rendered, noise-free frames: the 0.5 DN floor gives a finite threshold and SNR.
    rng = np.random.default_rng(6)
    leds = _scene(rng, 4.0, 50.0)
    res = detect_leds(render(SEQ.pattern, leds, rng, shape=SHAPE, sensor=NOISE_FREE), SEQ)
    assert res.noise.read_dn == 0.5
    assert res.found.all()
    assert all(np.isfinite(d.snr) and d.sigma_px < 0.01 for d in res.leds)


def test_dilation_setting_is_used() -> None:
    # Without dilation the sub-threshold edge of each disc is cut off: still a good
    # centroid for a symmetric disc, and the window is just the thresholded pixels.
    rng = np.random.default_rng(7)
    leds = _scene(rng, 6.0, 80.0)
    frames = render(SEQ.pattern, leds, rng, shape=SHAPE, sensor=NOISE_FREE_8BIT)
    res = detect_leds(frames, SEQ, config=DetectorConfig(dilate_px=0))
    assert res.found.all()
    centres = np.array([led.center for led in leds])
    assert _rms(res.pixels() - centres) < 0.05
