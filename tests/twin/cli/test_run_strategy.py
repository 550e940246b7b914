"""``twin run`` and ``twin montecarlo`` take the campaign's strategy by name, and refuse one
they do not know before writing anything."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from twin.campaign import PaperStrategy
from twin.campaign.strategies import STRATEGIES
from twin.cli import main

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


@pytest.mark.parametrize("command", ["run", "montecarlo"])
def test_an_unknown_strategy_on_the_command_line_is_refused(command, tmp_path, capsys):
    extra = ["--trials", "1"] if command == "montecarlo" else []
    with pytest.raises(SystemExit) as exit_:
        main([command, str(SMOKE), *extra, "--strategy", "bold", "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert "invalid choice: 'bold'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["run", "montecarlo"])
def test_an_unknown_strategy_in_the_scenario_is_refused(command, tmp_path, capsys):
    text = SMOKE.read_text().replace("[route]", '[campaign]\nstrategy = "bold"\n\n[route]')
    scenario = tmp_path / "bold.toml"
    scenario.write_text(text)
    extra = ["--trials", "1"] if command == "montecarlo" else []
    assert main([command, str(scenario), *extra, "--out", str(tmp_path / "o")]) == 2
    said = " ".join(capsys.readouterr().err.split())
    assert str(scenario) in said
    assert "campaign.strategy: unknown strategy (got 'bold')" in said
    assert "expected a strategy the campaign knows: paper, planned" in said
    assert not (tmp_path / "o").exists()


def test_the_strategy_is_built_once_and_is_in_the_results(tmp_path, monkeypatch):
    built = []

    def make() -> PaperStrategy:
        built.append(PaperStrategy())
        return built[-1]

    monkeypatch.setitem(STRATEGIES, "paper", make)
    out = tmp_path / "run"
    args = ["run", str(SMOKE), "--fidelity", "geometric", "--strategy", "paper", "--no-report"]
    assert main([*args, "--out", str(out)]) == 0
    assert len(built) == 1
    results = json.loads((out / "results.json").read_text())
    assert results["strategy"] == "paper"


def test_a_run_that_calibrated_nothing_exits_with_1(tmp_path, capsys):
    # The only visit's station is unreachable: the run finishes and calibrates nothing.
    text = SMOKE.read_text().replace("[route]", "[faults]\nunreachable = [[0.5, 0.0]]\n\n[route]")
    scenario = tmp_path / "blocked.toml"
    scenario.write_text(text)
    out = tmp_path / "run"
    args = ["run", str(scenario), "--fidelity", "geometric", "--no-report", "--out", str(out)]
    assert main(args) == 1
    results = json.loads((out / "results.json").read_text())
    assert results["calibrations"] == []
    assert results["skipped_visits"][0]["reason"] == "station_unreachable"


def test_a_run_that_drops_one_visit_exits_with_1_and_lists_it(tmp_path, capsys):
    # Two visits of cam1; the second's station is unreachable: the first calibrates, the
    # run still exits 1 and names the visit it dropped with the recorded reason.
    two = '{ camera = "cam1", station = [0.5, 0.0] }, { camera = "cam1", station = [2.0, 0.0] }'
    text = SMOKE.read_text().replace(
        '[{ camera = "cam1", station = [0.5, 0.0] }]',
        f"[{two}]\n\n[faults]\nunreachable = [[2.0, 0.0]]",
    )
    scenario = tmp_path / "dropped.toml"
    scenario.write_text(text)
    out = tmp_path / "run"
    args = ["run", str(scenario), "--fidelity", "geometric", "--no-report", "--out", str(out)]
    assert main(args) == 1
    said = capsys.readouterr().out
    results = json.loads((out / "results.json").read_text())
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == [("cam1", 1)]
    assert "dropped 1 of the scenario's 2 visits:" in said
    assert "  cam1 visit 2: station_unreachable: the parent stopped short" in said.splitlines()
    assert "cam1 visit 1:" not in said


def test_a_monte_carlo_run_that_calibrated_nothing_exits_with_1(tmp_path, capsys):
    text = SMOKE.read_text().replace("[route]", "[faults]\nunreachable = [[0.5, 0.0]]\n\n[route]")
    scenario = tmp_path / "blocked.toml"
    scenario.write_text(text)
    out = tmp_path / "mc"
    args = ["montecarlo", str(scenario), "--trials", "2", "--no-budget", "--out", str(out)]
    assert main([*args, "--fidelity", "geometric"]) == 1
    assert "no trial calibrated any camera" in " ".join(capsys.readouterr().out.split())
    assert (out / "summary.json").exists()


def test_the_batch_fidelity_refuses_a_scenario_with_faults(tmp_path, capsys):
    # The batch injects no faults: it says so, names the fidelity that does, writes nothing.
    text = SMOKE.read_text().replace("[route]", "[faults]\nunreachable = [[0.5, 0.0]]\n\n[route]")
    scenario = tmp_path / "blocked.toml"
    scenario.write_text(text)
    out = tmp_path / "mc"
    args = ["montecarlo", str(scenario), "--trials", "2", "--no-budget", "--out", str(out)]
    assert main(args) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert "the batch fidelity injects no faults" in said
    assert "sets [faults]; run it with --fidelity geometric" in said
    assert not out.exists()


def test_a_first_station_on_a_slope_ends_the_run_with_its_reason(tmp_path):
    # A floor patch tilted 30' (the inclinometer reads +-3') under the parent's start.
    text = SMOKE.read_text().replace(
        "[[space.floor_patches]]",
        '[[space.floor_patches]]\nname = "slope"\ncenter = [0.0, 0.0]\nsize = [1.2, 1.2]\n'
        "tilt_arcmin = [0.0, 30.0]\n\n[[space.floor_patches]]",
        1,
    )
    scenario = tmp_path / "slope.toml"
    scenario.write_text(text)
    out = tmp_path / "run"
    args = ["run", str(scenario), "--fidelity", "geometric", "--no-report", "--out", str(out)]
    assert main(args) == 1
    results = json.loads((out / "results.json").read_text())
    assert results["calibrations"] == []
    assert results["failures"]["tilt_out_of_range"] == 1
    assert results["failures"]["campaign_aborted"] == 1
