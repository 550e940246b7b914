"""The run's results table fits a log's 80 columns: no heading is cut short."""

from __future__ import annotations

from pathlib import Path

from rich.console import Console

from twin.cli.run import print_results
from twin.run.runner import run_scenario

SMOKE = Path(__file__).resolve().parents[3] / "scenarios" / "smoke.toml"


def test_the_results_table_fits_80_columns(tmp_path):
    results = run_scenario(SMOKE, tmp_path / "run", fidelity="geometric", report=False)
    console = Console(width=80, record=True)
    print_results(results, console)
    text = console.export_text()
    assert "…" not in text
    for heading in ("camera", "travel", "world", "local", "true", "err", "in mm"):
        assert heading in text, heading
    assert max(len(line.rstrip()) for line in text.splitlines()) <= 80
