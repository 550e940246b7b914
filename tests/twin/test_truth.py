"""The simulation's truth is read at the moments the campaign's estimates were made."""

import numpy as np

from twin.truth import instrument_truth


def _record(t, x):
    return {"timestamp": t, "translation": [x, 0.0, 0.0], "yaw": 0.0}


def test_each_time_gets_the_latest_truth_at_or_before_it():
    records = [_record(5.0, 2.0), _record(0.0, 0.0), _record(5.0, 3.0), _record(9.0, 4.0)]
    got = instrument_truth(records, [0.0, 4.9, 5.0, 8.0, 9.0, 100.0])
    assert [float(g[0]) for g in got] == [0.0, 0.0, 3.0, 3.0, 4.0, 4.0]


def test_a_time_before_any_truth_gets_none():
    assert instrument_truth([_record(1.0, 1.0)], [0.5]) == [None]
    assert instrument_truth([], [0.0]) == [None]


def test_the_truth_is_a_float_array():
    (got,) = instrument_truth([_record(0.0, 1.5)], [0.0])
    np.testing.assert_array_equal(got, [1.5, 0.0, 0.0])
