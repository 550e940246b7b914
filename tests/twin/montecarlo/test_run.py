"""Whole Monte-Carlo runs of the smoke scenario: the table is the same whatever the number
of workers, the engine, the chunk size, or an interruption; the outputs are written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from twin.montecarlo import run_montecarlo
from twin.montecarlo.engines import make_engine
from twin.montecarlo.figures import write_figures
from twin.montecarlo.run import SETTINGS, TABLE
from twin.outputs import OutputError
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
TRIALS = 4


def same_rows(a: list[dict], b: list[dict]) -> bool:
    """Row for row the same values, NaN (a visit or an adjustment without a value) equal
    to NaN."""

    def key(row: dict) -> dict:
        return {k: "nan" if isinstance(v, float) and v != v else v for k, v in row.items()}

    return [key(r) for r in a] == [key(r) for r in b]


@pytest.fixture(scope="module")
def smoke():
    return load_scenario(SMOKE)


@pytest.fixture(scope="module")
def reference(smoke, tmp_path_factory):
    """An uninterrupted run in this process (one worker, the batch fidelity)."""
    out = tmp_path_factory.mktemp("reference")
    rows = run_montecarlo(smoke, out, TRIALS, master_seed=11)
    return out, rows


@pytest.fixture(scope="module")
def geometric_reference(smoke, tmp_path_factory):
    """The same at the geometric fidelity (one trial a campaign)."""
    out = tmp_path_factory.mktemp("geometric")
    rows = run_montecarlo(smoke, out, TRIALS, master_seed=11, fidelity="geometric")
    return out, rows


def test_a_run_writes_its_table_summary_figures_and_report(reference):
    out, rows = reference
    assert len(rows) == TRIALS  # the smoke scenario plans one visit
    assert [r["trial"] for r in rows] == list(range(TRIALS))
    assert all(r["calibrated"] == 1 for r in rows)
    assert len({r["seed"] for r in rows}) == TRIALS
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials_done"] == TRIALS
    visit = summary["visits"][0]
    assert visit["position_error_mm"]["n"] == TRIALS
    assert visit["position_error_mm"]["median"] > 0
    assert summary["budget"] is None
    report = (out / "report.md").read_text()
    assert "Monte Carlo against the covariance propagation" in report


def test_the_figures_draw_the_trials(reference, tmp_path, saved):
    # Drawn again from the run's table and summary, watched: the same PNGs as the run wrote,
    # each the figure at its DPI, holding what the trials say.
    out, rows = reference
    summary = json.loads((out / "summary.json").read_text())
    write_figures(rows, summary, tmp_path)
    names = ("position_error_histograms.png", "error_vs_distance.png", "budget.png")
    assert set(saved) == set(names)
    for name in names:
        assert (tmp_path / name).read_bytes() == (out / "figures" / name).read_bytes(), name
        saved[name].check_png()
    errors = [r["position_error_mm"] for r in rows]
    visit = summary["visits"][0]
    # One histogram (one visit): its bars count every trial, its lines mark the median.
    (ax,) = saved["position_error_histograms.png"].figure.axes
    assert sum(bar.get_height() for bar in ax.patches) == TRIALS
    assert ax.patches[0].get_x() == pytest.approx(min(errors))
    assert ax.patches[-1].get_x() + ax.patches[-1].get_width() == pytest.approx(max(errors))
    assert any(np.allclose(ln.get_xdata(), np.median(errors)) for ln in ax.get_lines())
    # Error against distance: the median at the visit's median distance.
    (dots,) = saved["error_vs_distance.png"].lines("median")
    np.testing.assert_allclose(
        dots.get_xydata(), [[visit["distance_travelled_m"]["median"], np.median(errors)]]
    )
    # No one-source runs: the budget figure says so.
    assert "no one-source runs (run with the budget)" in saved["budget.png"].texts()


def test_the_table_is_the_same_with_two_worker_processes(smoke, reference, tmp_path):
    ref_out, ref_rows = reference
    rows = run_montecarlo(smoke, tmp_path, TRIALS, master_seed=11, workers=2, report=False)
    assert same_rows(rows, ref_rows)
    assert (tmp_path / TABLE).read_bytes() == (ref_out / TABLE).read_bytes()


def test_a_local_ray_instance_gives_the_same_rows(smoke, reference, tmp_path):
    import ray

    _, ref_rows = reference
    try:
        rows = run_montecarlo(
            smoke, tmp_path, TRIALS, master_seed=11, workers=2, engine="ray", report=False
        )
    finally:
        ray.shutdown()
    assert same_rows(rows, ref_rows)


def test_the_table_is_the_same_whatever_the_chunk_size(smoke, reference, tmp_path):
    # One trial an array, or three and one: each trial's draws are its own. Without the
    # report, the table and the summary are written and the figures and report.md are not.
    ref_out, ref_rows = reference
    for size in (1, 3):
        out = tmp_path / str(size)
        rows = run_montecarlo(smoke, out, TRIALS, master_seed=11, chunk_size=size, report=False)
        assert same_rows(rows, ref_rows)
        assert (out / TABLE).read_bytes() == (ref_out / TABLE).read_bytes()
        assert json.loads((out / "summary.json").read_text())["trials_done"] == TRIALS
        assert not (out / "report.md").exists()
        assert not (out / "figures").exists()


def test_a_batch_run_cut_short_resumes_to_the_same_table(smoke, reference, tmp_path):
    # A batch run killed after its first chunk leaves the table's first rows: resuming runs
    # the rest and the table is the uninterrupted run's, byte for byte.
    ref_out, _ = reference
    lines = (ref_out / TABLE).read_text().splitlines(keepends=True)
    (tmp_path / TABLE).write_text("".join(lines[:3]))
    (tmp_path / SETTINGS).write_text((ref_out / SETTINGS).read_text())
    rows = run_montecarlo(smoke, tmp_path, TRIALS, master_seed=11, resume=True, chunk_size=1)
    assert (tmp_path / TABLE).read_bytes() == (ref_out / TABLE).read_bytes()
    assert len(rows) == TRIALS


def test_a_killed_run_resumes_to_the_same_table(geometric_reference, tmp_path):
    ref_out, _ = geometric_reference
    cmd = [sys.executable, "-m", "twin.cli", "montecarlo", str(SMOKE), "--trials", str(TRIALS)]
    cmd += ["--seed", "11", "--no-budget", "--fidelity", "geometric", "--out", str(tmp_path)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    table = tmp_path / TABLE
    deadline = time.monotonic() + 120
    # Kill it once it has finished at least one trial and not all of them.
    while time.monotonic() < deadline:
        lines = table.read_text().count("\n") - 1 if table.exists() else 0
        if lines >= 1 or proc.poll() is not None:
            break
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    kept = table.read_text().count("\n") - 1
    assert 1 <= kept < TRIALS, proc.stderr.read().decode()[-2000:]
    smoke = load_scenario(SMOKE)
    with pytest.raises(ValueError, match="--resume"):
        run_montecarlo(smoke, tmp_path, TRIALS, master_seed=11, fidelity="geometric")
    rows = run_montecarlo(
        smoke, tmp_path, TRIALS, master_seed=11, fidelity="geometric", resume=True
    )
    assert table.read_bytes() == (ref_out / TABLE).read_bytes()
    assert len(rows) == TRIALS


def test_resuming_with_other_settings_is_refused(smoke, reference, tmp_path):
    ref_out, _ = reference
    (tmp_path / SETTINGS).write_text((ref_out / SETTINGS).read_text())
    with pytest.raises(ValueError, match="master_seed"):
        run_montecarlo(smoke, tmp_path, TRIALS, master_seed=12, resume=True)
    with pytest.raises(ValueError, match="fidelity"):
        run_montecarlo(smoke, tmp_path, TRIALS, master_seed=11, fidelity="render", resume=True)
    with pytest.raises(OutputError, match="holds no `twin montecarlo` run to resume"):
        run_montecarlo(smoke, tmp_path / "empty", TRIALS, resume=True)
    assert not (tmp_path / "empty").exists()
    other = smoke.model_copy(update={"seed": smoke.seed + 1})
    with pytest.raises(ValueError, match=r"made with another scenario .* --overwrite"):
        run_montecarlo(other, tmp_path, TRIALS, master_seed=11, resume=True)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"trials": 0}, "trials must be at least 1"),
        ({"trials": 1, "fidelity": "exact"}, "fidelity"),
        ({"trials": 1, "engine": "dask"}, "unknown engine"),
        ({"trials": 1, "workers": 0}, "workers must be at least 1"),
        ({"trials": 1, "ray_address": "auto"}, "--ray-address goes with --engine ray"),
        ({"trials": 1, "chunk_size": 0}, "chunk_size .* must be at least 1, got 0"),
        ({"trials": 1, "fidelity": "geometric", "chunk_size": 5}, "goes with the batch fidelity"),
    ],
)
def test_bad_settings_are_refused(smoke, tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        run_montecarlo(smoke, tmp_path, **kwargs)


def test_without_ray_the_ray_engine_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(RuntimeError, match=r"pip install 'camnet-twin\[cluster\]'"):
        make_engine("ray", 2)


def test_the_command_refuses_bad_settings_with_exit_code_2(tmp_path, capsys):
    from twin.cli import main

    base = ["montecarlo", str(SMOKE), "--trials", "1", "--out", str(tmp_path / "mc")]
    assert main([*base, "--ray-address", "auto"]) == 2
    assert "--ray-address goes with --engine ray" in capsys.readouterr().out
    assert main([*base, "--fidelity", "geometric", "--chunk-size", "5"]) == 2
    assert "--chunk-size goes with --fidelity batch" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_:
        main([*base, "--chunk-size", "0"])
    assert exit_.value.code == 2
    assert "--chunk-size: must be at least 1, got 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main([*base, "--fidelity", "exact"])
    assert exit_.value.code == 2
    assert "invalid choice: 'exact'" in capsys.readouterr().err
    assert main(["montecarlo", str(tmp_path / "none.toml"), "--trials", "1"]) == 2
    with pytest.raises(SystemExit) as exit_:
        main([*base[:2], "--trials", "0"])
    assert exit_.value.code == 2  # argparse's usage error, as the other refusals
    assert "--trials: must be at least 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "mc").exists()


def test_a_trial_that_raises_is_named_and_the_finished_ones_are_kept(tmp_path, monkeypatch, capsys):
    import twin.run.runner
    from twin.cli import main
    from twin.montecarlo.seeds import trial_seed

    real = twin.run.runner.run_scenario

    def second_fails(scenario, out_dir, **kwargs):
        if kwargs["seed"] == trial_seed(5, 1):
            raise ValueError("the children coincide")
        return real(scenario, out_dir, **kwargs)

    monkeypatch.setattr(twin.run.runner, "run_scenario", second_fails)
    out = tmp_path / "mc"
    args = ["montecarlo", str(SMOKE), "--trials", "3", "--seed", "5", "--no-budget"]
    assert main([*args, "--fidelity", "geometric", "--out", str(out)]) == 1
    said = " ".join(capsys.readouterr().out.split())
    assert f"trial 1 of 'all' (seed {trial_seed(5, 1)}) failed: ValueError: the children" in said
    # The command that runs it alone names the scenario's file and the strategy.
    alone = f"twin run {SMOKE} --fidelity geometric --seed {trial_seed(5, 1)} --strategy planned"
    assert alone in said
    assert "--resume continues" in said
    # Trial 0 ran before the failure and stays in the table for --resume.
    lines = (out / TABLE).read_text().splitlines()
    assert len(lines) == 2
    assert lines[1].startswith("all,0,")


def test_a_batch_chunk_that_raises_is_named_with_its_trials(tmp_path, monkeypatch, capsys):
    import twin.montecarlo.batch_trials
    from twin.cli import main

    class Broken:
        def __init__(self, *args, **kwargs):
            pass

        def run(self):
            raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(twin.montecarlo.batch_trials, "BatchRun", Broken)
    out = tmp_path / "mc"
    args = ["montecarlo", str(SMOKE), "--trials", "3", "--seed", "5", "--no-budget"]
    assert main([*args, "--out", str(out)]) == 1
    said = " ".join(capsys.readouterr().out.split())
    assert "trials 0-2 of 'all' at the batch fidelity failed: LinAlgError: Singular" in said
    assert "--resume continues" in said
    assert (out / TABLE).read_text().count("\n") == 1  # the header, no trial


def test_a_ray_address_nothing_answers_at_is_refused_within_seconds():
    import socket

    from twin.montecarlo.engines import check_ray_address

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # free once closed: nothing listens there
    t0 = time.monotonic()
    with pytest.raises(RuntimeError, match=f"no Ray cluster answers at 127.0.0.1:{port}"):
        check_ray_address(f"127.0.0.1:{port}", timeout_s=2.0)
    assert time.monotonic() - t0 < 5.0
    for bad in ("127.0.0.1:notaport", "ray://:10001", "127.0.0.1:70000"):
        with pytest.raises(ValueError, match="expected host:port"):
            check_ray_address(bad)
    check_ray_address("auto")  # left to Ray


def test_a_ray_address_that_answers_passes():
    import socket

    from twin.montecarlo.engines import check_ray_address

    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        check_ray_address(f"ray://127.0.0.1:{server.getsockname()[1]}", timeout_s=2.0)
