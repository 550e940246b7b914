"""The sensor model: its noise is the documented photon plus read noise, in DN."""

from __future__ import annotations

import numpy as np
import pytest

from twin.scenario.schema import SensorConfig
from twin.sim.sensor import dn_per_electron, expose, noise_dn


@pytest.mark.parametrize("level", [5.0, 60.0, 128.0, 220.0])
def test_noise_matches_photon_plus_read_noise(level):
    sensor = SensorConfig(blur_sigma_px=0.0)
    rng = np.random.default_rng(3)
    img = expose(np.full((250, 250), level, dtype=np.float32), sensor, rng).astype(float)
    # 62500 samples: the sample std is within 0.6 % (2 sigma) of the truth; rounding adds
    # 1/12 DN^2 of variance.
    want = np.sqrt(noise_dn(sensor, level) ** 2 + 1.0 / 12.0)
    assert img.std() == pytest.approx(want, rel=0.02)
    assert img.mean() == pytest.approx(level, abs=0.05)


def test_default_sensor_noise_is_that_of_an_old_small_camera():
    sensor = SensorConfig()
    assert 2.0 < noise_dn(sensor, 128.0) < 3.0
    assert 0.5 < noise_dn(sensor, 10.0) < 1.2


def test_noise_free_sensor_only_rounds_and_clips():
    sensor = SensorConfig(noise=False, blur_sigma_px=0.0, exposure=2.0)
    levels = np.array([[0.0, 10.2, 10.7, 100.0, 200.0]], dtype=np.float32)
    img = expose(levels, sensor, None)
    np.testing.assert_array_equal(img, [[0, 20, 21, 200, 255]])
    assert img.dtype == np.uint8
    np.testing.assert_array_equal(noise_dn(sensor, [10.0, 100.0]), [0.0, 0.0])


def test_more_bits_give_uint16_on_the_same_full_scale():
    sensor = SensorConfig(noise=False, blur_sigma_px=0.0, bits=12)
    img = expose(np.array([[255.0, 127.5]], dtype=np.float32), sensor, None)
    assert img.dtype == np.uint16
    np.testing.assert_array_equal(img, [[4095, 2048]])
    assert dn_per_electron(sensor) == pytest.approx(4095 / sensor.full_well_e)


def test_blur_keeps_the_light_and_spreads_it_by_sigma():
    sensor = SensorConfig(noise=False, blur_sigma_px=1.5, bits=16)
    levels = np.zeros((41, 41), dtype=np.float32)
    levels[20, 20] = 255.0
    img = expose(levels, sensor, None).astype(float)
    _, u = np.mgrid[0:41, 0:41]
    total = img.sum()
    assert total == pytest.approx(65535, rel=1e-3)
    var_u = (img * (u - 20) ** 2).sum() / total
    assert np.sqrt(var_u) == pytest.approx(1.5, rel=0.02)


def test_noisy_sensor_needs_a_generator():
    with pytest.raises(ValueError, match="random generator"):
        expose(np.zeros((4, 4), dtype=np.float32), SensorConfig(), None)


def test_same_seed_same_image():
    sensor = SensorConfig()
    levels = np.full((20, 20, 3), 90.0, dtype=np.float32)
    a = expose(levels, sensor, np.random.default_rng(7))
    b = expose(levels, sensor, np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)
