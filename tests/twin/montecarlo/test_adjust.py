"""``twin montecarlo --adjust``: the adjusted columns at the batch fidelity."""

from __future__ import annotations

import json
import math

from tests.twin.campaign.loop_scenario import ROOT, loop_scenario
from twin.cli import main
from twin.montecarlo import run_montecarlo
from twin.montecarlo.run import SETTINGS


def test_the_batch_fills_the_adjusted_columns_only_when_asked(tmp_path):
    sc = loop_scenario().model_copy(update={"control_points": ()})
    plain = run_montecarlo(sc, tmp_path / "plain", 3, master_seed=5)
    assert all(math.isnan(r["adjusted_position_error_mm"]) for r in plain)
    rows = run_montecarlo(sc, tmp_path / "adjusted", 3, master_seed=5, adjust=True)
    assert [r["position_error_mm"] for r in rows] == [r["position_error_mm"] for r in plain]
    for r in rows:
        assert r["adjusted_position_error_mm"] > 0
        assert r["adjusted_predicted_rms_mm"] > 0
    settings = json.loads((tmp_path / "adjusted" / SETTINGS).read_text())
    assert settings["adjust"] is True
    report = (tmp_path / "adjusted" / "report.md").read_text()
    assert "## Global adjustment" in report


def test_the_command_line_takes_adjust(tmp_path):
    code = main(
        [
            "montecarlo",
            str(ROOT / "scenarios" / "smoke.toml"),
            "--trials",
            "2",
            "--no-budget",
            "--adjust",
            "--out",
            str(tmp_path / "mc"),
        ]
    )
    assert code == 0
    # The smoke room calibrates its camera once: nothing is measured twice, no adjustment.
    assert json.loads((tmp_path / "mc" / SETTINGS).read_text())["adjust"] is True
