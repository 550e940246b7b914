"""What went wrong in a Monte-Carlo run reaches its table, its summary and its report: the
failures by kind, and why each visit that gave no calibration gave none."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from twin.montecarlo import ALL, COLUMNS, TrialSpec
from twin.montecarlo.report import render_report
from twin.montecarlo.summary import failure_summary
from twin.montecarlo.table import format_rows, read_table
from twin.montecarlo.trial import failure_kinds, trial_rows
from twin.scenario import load_scenario

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def _row(trial: int, calibrated: int, why: str = "", kinds: str = "") -> dict:
    row = {c: (0.0 if k is float else 0 if k is int else "") for c, k in COLUMNS.items()}
    row.update(config=ALL, trial=trial, seed=trial, camera="cam1", visit=1)
    row.update(calibrated=calibrated, not_calibrated=why, failure_kinds=kinds)
    return row


def test_an_aborted_trial_says_why_its_visit_gave_no_calibration():
    spec = TrialSpec(load_scenario(SMOKE), ALL, 0, 7, "geometric", "planned")
    results = {
        "calibrations": [],
        "failures": {"campaign_aborted": 1, "lost_lock": 2111, "led_partial": 0},
        "skipped_visits": [
            {
                "camera": "cam1",
                "visit": 1,
                "reason": "campaign_aborted",
                "message": "the parent cannot measure child2",
            }
        ],
    }
    (row,) = trial_rows(spec, results, [], None)
    assert row["calibrated"] == 0
    assert row["not_calibrated"] == "campaign_aborted: the parent cannot measure child2"
    assert row["failures"] == 2112
    assert row["failure_kinds"] == "campaign_aborted 1; lost_lock 2111"


def test_the_summary_counts_kinds_over_trials_and_reasons_over_visits():
    rows = [
        _row(0, 0, "campaign_aborted: the parent cannot measure child2", "lost_lock 3"),
        _row(1, 1, "", "lost_lock 2; shot_given_up 1"),
        _row(2, 0, "too_few_points: 20 points, 30 needed", ""),
        _row(3, 0, "campaign_aborted: no formation", "campaign_aborted 1"),
    ]
    out = failure_summary(rows)
    assert out["kinds"] == {"lost_lock": 5, "campaign_aborted": 1, "shot_given_up": 1}
    assert out["trials_with_failures"] == 3
    assert out["not_calibrated"] == {"campaign_aborted": 2, "too_few_points": 1}


@settings(max_examples=50, deadline=None)
@given(
    per_trial=st.lists(
        st.dictionaries(
            st.from_regex(r"[a-z][a-z_]{0,15}", fullmatch=True), st.integers(0, 10**6), max_size=5
        ),
        min_size=1,
        max_size=4,
    )
)
def test_kinds_survive_the_table_file(per_trial, tmp_path_factory):
    rows = [_row(k, 1, "", failure_kinds(kinds)) for k, kinds in enumerate(per_trial)]
    path = tmp_path_factory.mktemp("t") / "trials.csv"
    path.write_text(",".join(COLUMNS) + "\n" + format_rows(rows), encoding="utf-8")
    totals: dict[str, int] = {}
    for kinds in per_trial:
        for kind, n in kinds.items():
            if n:
                totals[kind] = totals.get(kind, 0) + n
    assert failure_summary(read_table(path))["kinds"] == totals


def test_the_report_has_a_failures_section_only_where_something_failed(tmp_path):
    summary = {
        "scenario": "smoke",
        "fidelity": "render",
        "master_seed": 1,
        "trials_done": 1,
        "configurations": [ALL],
        "visits": [],
        "parent_final": {},
        "budget": None,
        "paper": None,
    }
    failed = {"kinds": {"lost_lock": 3}, "trials_with_failures": 1, "not_calibrated": {}}
    failed["not_calibrated"] = {"campaign_aborted": 1}
    text = render_report({**summary, "failures": failed}, {}, tmp_path)
    assert "## Failures" in text
    assert "| campaign_aborted | 1 |" in text
    assert "| lost_lock | 3 |" in text
    clean = {"kinds": {}, "trials_with_failures": 0, "not_calibrated": {}}
    assert "## Failures" not in render_report({**summary, "failures": clean}, {}, tmp_path)
