"""Specification checks."""

import pytest

from twin.instruments.total_station import InclinometerSpec, TotalStationSpec


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"angle_sigma": -1.0}, "angle_sigma"),
        ({"distance_resolution": float("nan")}, "distance_resolution"),
        ({"range_min": 10.0, "range_max": 5.0}, "range_max"),
        ({"aim_cone": 0.0}, "aim_cone"),
        ({"aim_cone": 2.0}, "aim_cone"),
    ],
)
def test_total_station_spec_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TotalStationSpec(**kwargs)


def test_inclinometer_spec_rejects_bad_values():
    with pytest.raises(ValueError, match="working_range"):
        InclinometerSpec(working_range=0.0)
    with pytest.raises(ValueError, match="sigma"):
        InclinometerSpec(sigma=-1.0)
