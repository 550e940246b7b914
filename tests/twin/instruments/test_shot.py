"""A complete simulated shot: tilt, aim, noise, levelling, rounding, typed failures."""

import numpy as np
import pytest

from twin.instruments.errors import (
    FailureReason,
    InstrumentError,
    LineOfSightBlockedError,
    NoPrismInConeError,
    OutOfRangeError,
    TiltOutOfRangeError,
)
from twin.instruments.shot import simulate_shot
from twin.instruments.tilt import tilt_rotation
from twin.instruments.total_station import ARCSEC, InclinometerSpec, TotalStationSpec

EXACT = TotalStationSpec.noiseless()
EXACT_INCL = InclinometerSpec(sigma=0.0)


def test_noise_free_tilted_shot_reports_the_level_position():
    level = np.array([[12.0, 3.0, 0.6], [11.0, -4.0, 0.5]])
    tilt = (90 * ARCSEC, -120 * ARCSEC)
    instrument = level @ tilt_rotation(*tilt)  # rows: R^T p
    shot = simulate_shot(
        instrument,
        level[1],
        EXACT,
        np.random.default_rng(0),
        true_tilt=tilt,
        inclinometer=EXACT_INCL,
        timestamp=3.5,
    )
    assert shot.prism_index == 1
    np.testing.assert_allclose(shot.measurement.to_cartesian(), level[1], atol=1e-12)
    assert shot.measurement.timestamp == 3.5
    assert shot.measurement.tilt.roll == pytest.approx(tilt[0])


def test_uncompensated_shot_keeps_the_tilt_error():
    level = np.array([[50.0, 0.0, 0.0]])
    tilt = (0.0, 120 * ARCSEC)
    instrument = level @ tilt_rotation(*tilt)
    shot = simulate_shot(instrument, level[0], EXACT, np.random.default_rng(0), true_tilt=tilt)
    assert shot.measurement.tilt is None
    err = shot.measurement.to_cartesian() - level[0]
    assert np.abs(err[2]) == pytest.approx(50.0 * 120 * ARCSEC, rel=1e-3)


def test_shots_are_rounded_and_reproducible():
    prism = np.array([[31.4, 2.7, 1.1]])

    def shoot(seed):
        return simulate_shot(
            prism,
            prism[0],
            TotalStationSpec(),
            np.random.default_rng(seed),
            inclinometer=InclinometerSpec(),
            true_tilt=(10 * ARCSEC, 5 * ARCSEC),
        ).measurement

    a, b, c = shoot(9), shoot(9), shoot(10)
    assert a.polar.tolist() == b.polar.tolist()
    assert a.polar.tolist() != c.polar.tolist()
    assert abs(a.distance / 0.2e-3 - round(a.distance / 0.2e-3)) < 1e-6
    assert abs(a.horizontal / ARCSEC - round(a.horizontal / ARCSEC)) < 1e-6
    assert np.linalg.norm(a.to_cartesian() - prism[0]) < 0.02


@pytest.mark.parametrize(
    ("prisms", "aim", "tilt", "los", "error", "reason"),
    [
        (
            [[3000.0, 0, 0]],
            [3000.0, 0, 0],
            (0.0, 0.0),
            None,
            OutOfRangeError,
            FailureReason.OUT_OF_RANGE,
        ),
        (
            [[10.0, 0, 0]],
            [0.0, 10.0, 0],
            (0.0, 0.0),
            None,
            NoPrismInConeError,
            FailureReason.NO_PRISM_IN_CONE,
        ),
        (
            [[10.0, 0, 0]],
            [10.0, 0, 0],
            (0.0, 0.0),
            lambda i, p: False,
            LineOfSightBlockedError,
            FailureReason.LINE_OF_SIGHT_BLOCKED,
        ),
        (
            [[10.0, 0, 0]],
            [10.0, 0, 0],
            (0.0, 4 * 60 * ARCSEC),
            None,
            TiltOutOfRangeError,
            FailureReason.TILT_OUT_OF_RANGE,
        ),
    ],
)
def test_typed_failures(prisms, aim, tilt, los, error, reason):
    with pytest.raises(error) as info:
        simulate_shot(
            np.array(prisms),
            np.array(aim),
            TotalStationSpec(),
            np.random.default_rng(0),
            true_tilt=tilt,
            inclinometer=InclinometerSpec(),
            line_of_sight=los,
        )
    assert isinstance(info.value, InstrumentError)
    assert info.value.reason is reason
