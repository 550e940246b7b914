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


@pytest.mark.parametrize(("seed", "episodes"), [(2**63 - 1, 2), (2**63 - 2, 3), (2**63 - 20, 22)])
def test_an_episode_seed_beyond_the_range_is_refused(seed, episodes, tmp_path, capsys):
    out = tmp_path / "s"
    argv = ["strategies", str(SMOKE), "--seed", str(seed), "--episodes", str(episodes)]
    assert main([*argv, "--out", str(out)]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert f"--seed {seed} with --episodes {episodes}" in said
    assert f"the last episode's seed {seed + episodes - 1} is above 2^63 - 1" in said
    assert f"expected --seed from 0 to {2**63 - episodes}" in said
    assert not out.exists()


def test_the_last_seed_of_the_range_is_played(tmp_path, monkeypatch):
    import twin.envs.comparison

    class Played(Exception):
        pass

    def play(scenario, policies, episodes, seed, **kwargs):
        raise Played(seed + episodes - 1)

    monkeypatch.setattr(twin.envs.comparison, "play_episodes", play)
    argv = ["strategies", str(SMOKE), "--seed", str(2**63 - 2), "--episodes", "2"]
    with pytest.raises(Played) as played:
        main([*argv, "--out", str(tmp_path / "s")])
    assert played.value.args == (2**63 - 1,)
