"""Trial seeds, one-source scenarios and the trial table: pure parts, checked exactly."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.montecarlo import ALL, COLUMNS, SOURCES, isolate, trial_seed
from twin.montecarlo.sources import configurations
from twin.montecarlo.table import TrialTable, format_rows, read_table, sort_rows
from twin.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


# -- seeds -------------------------------------------------------------------------------------
@given(st.integers(0, 2**63), st.integers(0, 10**6))
def test_a_trial_seed_depends_on_the_master_seed_and_index_only(master, trial):
    s = trial_seed(master, trial)
    assert s == trial_seed(master, trial)
    assert 0 <= s < 2**32


def test_trial_seeds_differ_between_trials_and_master_seeds():
    seeds = {trial_seed(1, i) for i in range(2000)}
    assert len(seeds) == 2000
    assert trial_seed(1, 0) != trial_seed(2, 0)


@pytest.mark.parametrize(("master", "trial"), [(-1, 0), (0, -3)])
def test_negative_seeds_and_indices_are_refused(master, trial):
    with pytest.raises(ValueError, match="non-negative"):
        trial_seed(master, trial)


# -- sources -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def hall():
    sc = load_scenario(SCENARIOS / "paper_hall.toml")
    ts = sc.noise.total_station.model_copy(update={"pointing_sigma": 1e-3})
    update = {
        "marker_geometry_m": 1e-3,
        "led_centroid_px": 0.5,
        "child_creep_m": 1e-3,
        "total_station": ts,
    }
    return sc.model_copy(update={"noise": sc.noise.model_copy(update=update)})


def _active(sc) -> set[str]:
    """Which sources of ``sc`` are noisy."""
    n, ts = sc.noise, sc.noise.total_station
    on = {
        "distance": ts.distance_sigma_const > 0 or ts.distance_sigma_ppm > 0,
        "angle": ts.angle_sigma > 0,
        "pointing": ts.pointing_sigma > 0,
        "inclination": n.inclinometer.sigma > 0,
        "led_detection": n.led_detection_px > 0 or any(c.sensor.noise for c in sc.cameras),
        "led_centroid": n.led_centroid_px > 0,
        "stopping": n.stopping.sigma_xy > 0 or n.odometry.distance_noise > 0,
        "creep": n.child_creep_m > 0,
        "marker": n.marker_geometry_m > 0,
    }
    return {k for k, v in on.items() if v}


def test_the_hall_has_every_source_and_all_keeps_them(hall):
    assert _active(hall) == set(SOURCES)
    assert isolate(hall, ALL) is hall


@pytest.mark.parametrize("source", list(SOURCES))
def test_isolating_a_source_keeps_it_alone_at_its_full_size(hall, source):
    alone = isolate(hall, source)
    assert _active(alone) == {source}
    if source == "distance":
        assert alone.noise.total_station.distance_sigma_const == (
            hall.noise.total_station.distance_sigma_const
        )
        assert alone.noise.total_station.angle_resolution == 0.0
    if source == "angle":
        assert alone.noise.total_station.angle_sigma == hall.noise.total_station.angle_sigma
        assert alone.noise.total_station.distance_resolution == 0.0
    # Nothing but the noise changes.
    assert alone.space == hall.space
    assert alone.route == hall.route
    assert alone.marker == hall.marker


def test_an_unknown_source_is_refused_with_the_known_ones(hall):
    with pytest.raises(ValueError, match="distance, angle"):
        isolate(hall, "temperature")


def test_configurations_list_all_first():
    assert configurations(False) == (ALL,)
    assert configurations(True) == (ALL, *SOURCES)


# -- table -------------------------------------------------------------------------------------
def _row(config: str, trial: int, visit: int, x: float = 1.5) -> dict:
    row = {c: (0.0 if k is float else 0 if k is int else "") for c, k in COLUMNS.items()}
    row.update(config=config, trial=trial, seed=100 + trial, camera="cam1", visit=visit)
    row.update(position_error_mm=x, rotation_error_deg=math.nan)
    return row


finite = st.floats(allow_nan=False, allow_infinity=True)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=5))
def test_the_table_reads_back_exactly_what_was_written(tmp_path_factory, values):
    path = tmp_path_factory.mktemp("t") / "trials.csv"
    rows = []
    for i, (a, b) in enumerate(values):
        r = _row(ALL, i, 1, a)
        r["world_pixel_mean"] = b
        rows.append(r)
    with TrialTable(path, rows_per_trial=1) as table:
        for r in rows:
            table.append([r])
    back = read_table(path)
    assert len(back) == len(rows)
    for r, b in zip(rows, back, strict=True):
        assert b["position_error_mm"] == r["position_error_mm"]
        assert b["world_pixel_mean"] == r["world_pixel_mean"]
        assert math.isnan(b["rotation_error_deg"])
        assert b["trial"] == r["trial"]
        assert b["config"] == r["config"]


def test_a_cut_line_and_a_half_written_trial_are_dropped_on_reopening(tmp_path):
    path = tmp_path / "trials.csv"
    with TrialTable(path, rows_per_trial=2) as table:
        table.append([_row(ALL, 0, 1), _row(ALL, 0, 2)])
        table.append([_row(ALL, 1, 1), _row(ALL, 1, 2)])
    text = path.read_text()
    # A kill in the middle of trial 2's write: one whole row, then half a line.
    lines = format_rows([_row(ALL, 2, 1), _row(ALL, 2, 2)]).splitlines()
    path.write_text(text + lines[0] + "\n" + lines[1][:10])
    table = TrialTable(path, rows_per_trial=2)
    table.close()
    assert table.done == {(ALL, 0), (ALL, 1)}
    assert [(r["trial"], r["visit"]) for r in read_table(path)] == [(0, 1), (0, 2), (1, 1), (1, 2)]


def test_a_trial_with_the_wrong_number_of_rows_is_refused(tmp_path):
    with (
        TrialTable(tmp_path / "t.csv", rows_per_trial=2) as table,
        pytest.raises(ValueError, match="2 rows"),
    ):
        table.append([_row(ALL, 0, 1)])


def test_a_file_that_is_not_a_trial_table_is_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("a,b,c\n1,2,3\n")
    with pytest.raises(ValueError, match="not a trial table"):
        read_table(path)
    path.write_text(",".join(COLUMNS) + "\n" + "1,2\n")
    with pytest.raises(ValueError, match=r"t\.csv:2"):
        read_table(path)
    # An earlier version's table (fewer columns) says so, and what to do.
    older = [c for c in COLUMNS if c not in ("not_calibrated", "failure_kinds")]
    path.write_text(",".join(older) + "\n")
    with pytest.raises(ValueError, match=r"earlier version.*not_calibrated.*--overwrite"):
        read_table(path)


def test_rows_sort_by_configuration_then_trial_keeping_visit_order():
    rows = [_row("angle", 0, 1), _row(ALL, 1, 2), _row(ALL, 1, 1), _row(ALL, 0, 1)]
    out = sort_rows(rows, (ALL, "angle"))
    assert [(r["config"], r["trial"], r["visit"]) for r in out] == [
        (ALL, 0, 1),
        (ALL, 1, 2),
        (ALL, 1, 1),
        ("angle", 0, 1),
    ]
