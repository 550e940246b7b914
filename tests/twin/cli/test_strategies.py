"""``twin strategies``: policies compared in the environment, a table, a CSV and a figure."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from twin.cli import main

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


def test_compares_policies_and_writes_the_tradeoff(tmp_path, capsys):
    out = tmp_path / "strategies"
    code = main(
        [
            "strategies",
            str(SMOKE),
            "--policy",
            "paper",
            "random",
            "--episodes",
            "3",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    said = capsys.readouterr().out
    assert "paper" in said
    assert "random" in said
    assert "steps/s" in said
    rows = list(csv.DictReader((out / "episodes.csv").open()))
    assert [r["policy"] for r in rows] == ["paper"] * 3 + ["random"] * 3
    assert [int(r["seed"]) for r in rows] == [0, 1, 2, 0, 1, 2]
    paper = [r for r in rows if r["policy"] == "paper"]
    assert all(float(r["error_cam1_mm"]) > 0 for r in paper)
    summary = json.loads((out / "summary.json").read_text())
    assert [s["policy"] for s in summary] == ["paper", "random"]
    assert summary[0]["calibrated"] == 1.0
    assert (out / "tradeoff.png").read_bytes()[:4] == b"\x89PNG"
    # A second run into the same folder is refused without --overwrite.
    assert main(["strategies", str(SMOKE), "--episodes", "1", "--out", str(out)]) == 2


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--policy", "clever"], "invalid choice: 'clever'"),
        (["--episodes", "0"], "must be at least 1"),
        (["--budget", "-3"], "expected a finite number above 0"),
        (["--planner", "grid"], "invalid choice: 'grid'"),
    ],
)
def test_bad_arguments_are_refused(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["strategies", str(SMOKE), *argv, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_missing_scenario_is_refused(tmp_path):
    assert main(["strategies", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_the_stands_planner_plays_the_same_policies(tmp_path, capsys):
    out = tmp_path / "stands"
    argv = ["strategies", str(SMOKE), "--policy", "paper", "--episodes", "2"]
    assert main([*argv, "--planner", "stands", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "episodes.csv").open()))
    assert [r["policy"] for r in rows] == ["paper"] * 2
    assert all(float(r["error_cam1_mm"]) > 0 for r in rows)
