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


def test_a_policy_on_a_test_set_against_a_baseline_writes_its_rows(tmp_path, capsys):
    """The smoke test set's first episode, paper against greedy: every row written, the
    test set's seed, and the paired difference equal to the rows' difference."""
    from twin.envs.heldout import test_set

    out = tmp_path / "t"
    argv = ["strategies", "--test-set", "smoke", "--episodes", "1", "--policy", "paper"]
    assert main([*argv, "--baseline", "greedy", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "paired by seed: policy - greedy" in said
    rows = list(csv.DictReader((out / "episodes.csv").open()))
    seed = test_set("smoke").seeds.start
    assert [(r["policy"], int(r["seed"])) for r in rows] == [("greedy", seed), ("paper", seed)]
    for r in rows:
        assert float(r["reward"]) > 0  # the camera calibrated: the predicted error fell
        assert 0 < float(r["true_error_mm"]) < 100
        assert float(r["distance_m"]) >= 0
        assert float(r["time_s"]) > 0
        assert float(r["true_error_mm"]) == pytest.approx(float(r["mean_camera_error_mm"]))
    differences = {d["metric"]: d for d in csv.DictReader((out / "differences.csv").open())}
    assert set(differences) == {
        "true_error_mm",
        "mean_camera_error_mm",
        "reward",
        "distance_m",
        "time_s",
    }
    for metric, d in differences.items():
        assert (d["policy"], d["baseline"], d["pairs"]) == ("paper", "greedy", "1")
        expected = float(rows[1][metric]) - float(rows[0][metric])
        assert float(d["mean"]) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--test-set", "nope"], "invalid choice: 'nope'"),
        (["--test-set", "smoke", "--policy", "clever"], "invalid choice: 'clever'"),
        (["--test-set", "smoke", "--baseline", "clever"], "invalid choice: 'clever'"),
    ],
)
def test_an_unknown_test_set_or_policy_is_named(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["strategies", *argv, "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--test-set", "smoke", str(SMOKE)], f"scenario {SMOKE} with --test-set smoke"),
        (["--test-set", "smoke", "--seed", "3"], "--seed with --test-set smoke"),
        (["--test-set", "smoke", "--episodes", "4"], "--episodes 4 with --test-set smoke"),
        ([], "expected a scenario file, 'random', or --test-set NAME"),
    ],
)
def test_a_test_set_with_contradicting_options_is_refused(argv, message, tmp_path, capsys):
    assert main(["strategies", *argv, "--out", str(tmp_path / "o")]) == 2
    assert message in " ".join(capsys.readouterr().out.split())
    assert not (tmp_path / "o").exists()


def test_a_missing_model_is_named(tmp_path, capsys):
    model = tmp_path / "models" / "ppo.zip"
    argv = ["strategies", "--test-set", "smoke", "--policy", str(model), "greedy"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert f"policy {model}: no such file" in said
    assert not (tmp_path / "o").exists()


def test_a_model_without_sb3_contrib_is_named(tmp_path, capsys, monkeypatch):
    import sys

    model = tmp_path / "ppo.zip"
    model.write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip
    monkeypatch.setitem(sys.modules, "sb3_contrib", None)  # as if not installed
    argv = ["strategies", "--test-set", "smoke", "--policy", str(model)]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert f"policy {model}: loading a saved model needs sb3-contrib" in said
    assert not (tmp_path / "o").exists()


def test_the_default_test_set_is_held_out_from_training():
    from twin.envs.heldout import DEFAULT_TEST_SET, TEST_SETS, TRAINING_SEEDS

    assert TEST_SETS[DEFAULT_TEST_SET].episodes >= 100
    assert TEST_SETS[DEFAULT_TEST_SET].scenario == "random"
    ranges = [TRAINING_SEEDS, *(t.seeds for t in TEST_SETS.values())]
    for i, a in enumerate(ranges):
        for b in ranges[i + 1 :]:
            assert a.stop <= b.start or b.stop <= a.start  # no seed in two of them
