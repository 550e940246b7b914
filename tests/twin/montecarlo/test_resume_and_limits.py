"""``twin montecarlo --resume`` with other settings, and the bound on ``--trials``: a
setting that changes the numbers is refused (exit code 2, nothing written), more trials
continue the run; a count the table cannot hold is refused at once, and the trials of a
run are made as they are needed."""

from __future__ import annotations

import itertools
import json
import math
import re
import shutil
import time
import tracemalloc
from pathlib import Path

import pytest

from twin.cli import main
from twin.montecarlo import TrialResult, run_montecarlo
from twin.montecarlo.batch_trials import chunks
from twin.montecarlo.engines import LocalEngine
from twin.montecarlo.run import MAX_TABLE_ROWS, SETTINGS, TABLE, check_trials, trial_specs
from twin.montecarlo.seeds import trial_seed
from twin.montecarlo.sources import configurations
from twin.montecarlo.trial import COLUMNS, row_key
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
TRIALS = 3
SEED = 11


@pytest.fixture(scope="module")
def smoke():
    return load_scenario(SMOKE)


@pytest.fixture(scope="module")
def adjusted_run(smoke, tmp_path_factory):
    """A finished batch run of 3 trials with --adjust, no budget, seed 11."""
    out = tmp_path_factory.mktemp("adjusted") / "mc"
    run_montecarlo(smoke, out, TRIALS, master_seed=SEED, adjust=True)
    return out


def snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file under ``folder`` with its bytes and modification time (ns)."""
    return {
        str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"adjust": False}, "adjust = True (--adjust), this one False"),
        ({"master_seed": 12}, "master_seed = 11 (--seed), this one 12"),
        ({"fidelity": "geometric"}, "fidelity = 'batch' (--fidelity), this one 'geometric'"),
        ({"strategy": "paper"}, "strategy = 'planned' (--strategy), this one 'paper'"),
        ({"budget": True}, "configurations = ['all'] (--no-budget), this one ['all', 'distance'"),
        ({"trials": 2}, "trials = 3 (--trials), this one 2; a resumed run may go on to more"),
    ],
)
def test_resuming_with_a_setting_that_changes_the_numbers_is_refused(
    smoke, adjusted_run, tmp_path, change, message
):
    out = tmp_path / "mc"
    shutil.copytree(adjusted_run, out)
    before = snapshot(out)
    kwargs = {"master_seed": SEED, "adjust": True, "trials": TRIALS, **change}
    trials = kwargs.pop("trials")
    with pytest.raises(
        ValueError, match=re.escape(f"{out}: cannot resume: the run there has {message}")
    ):
        run_montecarlo(smoke, out, trials, resume=True, **kwargs)
    assert snapshot(out) == before


def test_the_command_refuses_a_resume_without_adjust_or_with_fewer_trials(
    adjusted_run, tmp_path, capsys
):
    out = tmp_path / "mc"
    shutil.copytree(adjusted_run, out)
    before = snapshot(out)
    base = ["montecarlo", str(SMOKE), "--seed", str(SEED), "--no-budget", "--out", str(out)]
    assert main([*base, "--trials", str(TRIALS), "--resume"]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert "cannot resume: the run there has adjust = True (--adjust), this one False" in said
    assert main([*base, "--trials", "2", "--adjust", "--resume"]) == 2
    said = " ".join(capsys.readouterr().out.split())
    assert "the run there has trials = 3 (--trials), this one 2" in said
    assert snapshot(out) == before


def test_resuming_with_more_trials_continues_to_the_new_count(smoke, adjusted_run, tmp_path):
    # Two trials, then a resume to three with another chunk size (how it runs, not what):
    # the table is the three-trial run's, byte for byte, and the run says three.
    out = tmp_path / "mc"
    run_montecarlo(smoke, out, 2, master_seed=SEED, adjust=True)
    rows = run_montecarlo(
        smoke, out, TRIALS, master_seed=SEED, adjust=True, resume=True, chunk_size=1
    )
    assert [r["trial"] for r in rows] == list(range(TRIALS))
    assert (out / TABLE).read_bytes() == (adjusted_run / TABLE).read_bytes()
    assert json.loads((out / SETTINGS).read_text())["trials"] == TRIALS
    assert json.loads((out / "summary.json").read_text())["trials_done"] == TRIALS


def test_a_count_the_table_cannot_hold_is_refused_at_once_naming_the_limit(tmp_path, capsys):
    out = tmp_path / "mc"
    t0 = time.monotonic()
    assert main(["montecarlo", str(SMOKE), "--trials", "1000000000000", "--out", str(out)]) == 2
    assert time.monotonic() - t0 < 5.0
    said = " ".join(capsys.readouterr().out.split())
    # The smoke room plans one visit; with the budget a trial is 10 rows.
    assert "--trials 1000000000000: the trial table would have 10000000000000 rows" in said
    assert f"more than the {MAX_TABLE_ROWS} a run holds" in said
    assert f"at most --trials {MAX_TABLE_ROWS // 10} here" in said
    assert not out.exists()


def test_the_largest_count_passes_and_one_more_is_refused(smoke):
    for budget in (False, True):
        configs = configurations(budget)
        most = MAX_TABLE_ROWS // len(configs)  # one planned visit
        check_trials(smoke, most, configs)
        with pytest.raises(ValueError, match=f"at most --trials {most} here"):
            check_trials(smoke, most + 1, configs)


def test_the_help_states_the_limit(capsys):
    with pytest.raises(SystemExit):
        main(["montecarlo", "--help"])
    assert f"{MAX_TABLE_ROWS:,}" in " ".join(capsys.readouterr().out.split())


def test_trials_are_made_as_they_are_asked_for(smoke):
    # A trillion trials: the first chunk comes at once, and in order.
    configs = configurations(True)
    specs = trial_specs(smoke, configs, 10**12, SEED, "batch", "planned", {("all", 1)})
    first = next(chunks(None, specs, 200))  # type: ignore[arg-type]
    assert [s.trial for s in first.specs] == [0, *range(2, 201)]
    assert {s.config for s in first.specs} == {"all"}
    assert first.specs[-1].seed == trial_seed(SEED, 200)
    # The next configuration starts a chunk of its own.
    tail = trial_specs(smoke, configs[:2], 3, SEED, "batch", "planned")
    sizes = [(c.specs[0].config, len(c.specs)) for c in chunks(None, tail, 2)]  # type: ignore[arg-type]
    assert sizes == [("all", 2), ("all", 1), (configs[1], 2), (configs[1], 1)]
    # The engine takes items as it goes: an endless iterator is fine.
    squares = LocalEngine(1).imap_unordered(lambda x: x * x, itertools.count())
    assert list(itertools.islice(squares, 4)) == [0, 1, 4, 9]


def _row(spec) -> dict:
    empty = {c: 0 if t is int else math.nan if t is float else "" for c, t in COLUMNS.items()}
    return {**empty, **row_key(spec, "cam1", 1)}


def test_a_run_of_the_most_trials_starts_with_little_memory(smoke, tmp_path, monkeypatch):
    # Two million trials, interrupted after the third: the run does not build them first
    # (a trial made more than a chunk ahead of those run fails at once).
    import twin.montecarlo.run

    done: list[int] = []
    made: list[int] = []

    def seed(master: int, i: int) -> int:
        made.append(i)
        assert len(made) <= len(done) + 10, f"{len(made)} trials made, {len(done)} run"
        return trial_seed(master, i)

    def trial(spec):
        if len(done) == 3:
            raise KeyboardInterrupt("enough")
        done.append(spec.trial)
        return TrialResult(spec, (_row(spec),), 0.0)

    monkeypatch.setattr(twin.montecarlo.run, "trial_seed", seed)
    tracemalloc.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_montecarlo(
                smoke, tmp_path / "mc", MAX_TABLE_ROWS, fidelity="geometric", trial_fn=trial
            )
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20e6, f"{peak / 1e6:.0f} MB"
    assert done == [0, 1, 2]
    assert (tmp_path / "mc" / TABLE).read_text().count("\n") == 4  # the header, 3 trials
