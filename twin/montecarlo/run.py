"""A Monte-Carlo run: N trials of a scenario's campaign per noise configuration, written
to a trial table as they finish, then summarised.

``DIR/montecarlo.json`` holds what defines the run (scenario, fidelity, strategy, master
seed, configurations, ``adjust`` at the batch fidelity, trials); ``--resume`` refuses any
change to it but more trials, and runs only the trials the table lacks. Trials are made as
the engine asks for them, so a run's memory does not grow with its count; the table it
keeps, sorts and summarises does, hence :data:`MAX_TABLE_ROWS`.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.batch.steps import record_plan
from twin.campaign.strategies import strategy_name
from twin.montecarlo.batch_trials import (
    BATCH_OMITS,
    check_batch_scenario,
    chunks,
    default_chunk_size,
    run_batch_chunk,
)
from twin.montecarlo.engines import make_engine
from twin.montecarlo.seeds import trial_seed
from twin.montecarlo.sources import configurations, unpredicted
from twin.montecarlo.table import TrialTable
from twin.montecarlo.trial import TrialSpec, run_trial
from twin.outputs import MANIFEST, check_folder, claim_folder, write_text_atomic
from twin.report.reading import planned_visits
from twin.scenario import Scenario
from twin.scenario.digest import scenario_digest
from twin.scenario.limits import check_seed

FIDELITIES = ("batch", "geometric", "render")
"""The fidelities a Monte-Carlo run can use (``batch`` by default)."""

TABLE = "trials.csv"
SETTINGS = "montecarlo.json"
SUMMARY = "summary.json"
OUTPUTS = (TABLE, SETTINGS, SUMMARY, "figures", "report.md")
"""What a Monte-Carlo run writes in its folder (and clears there with ``overwrite``)."""

MAX_TABLE_ROWS = 2_000_000
"""Rows a run's trial table may hold (trials x configurations x planned visits): the run
keeps its table in memory to sort and summarise it, about 2.5 kB a row (measured on the
smoke room: 10 000 trials took 22 MB more than 1000), so 2 million rows take about 5 GB
(and 0.9 GB on disk, about 430 bytes a row)."""

RESULT_SETTINGS: dict[str, str] = {
    "fidelity": "--fidelity",
    "strategy": "--strategy",
    "master_seed": "--seed",
    "configurations": "--no-budget",
    "adjust": "--adjust",
}
"""The settings of ``montecarlo.json`` that define a run's numbers besides its scenario and
trials, with the option that sets each: a resumed run must have the same."""


@dataclass(frozen=True)
class McProgress:
    """Where a run stands: trials done of the total (this session's rate, s^-1)."""

    done: int
    total: int
    rate: float
    last: TrialSpec | None = None


def _settings(
    scenario: Scenario, fidelity: str, strategy: str, master_seed: int, configs: tuple
) -> dict:
    return {
        "scenario": scenario.name,
        "scenario_file": scenario.source,
        "scenario_digest": scenario_digest(scenario),
        "fidelity": fidelity,
        "strategy": strategy,
        "master_seed": master_seed,
        "configurations": list(configs),
        "unpredicted_sources": unpredicted(scenario),
    }


def _check_resume(path: Path, settings: dict[str, Any], trials: int) -> None:
    """Refuse to resume the run whose settings are at ``path`` with other ``settings`` (or
    fewer ``trials``); nothing is written.

    Raises:
        FileNotFoundError: there are no settings. ValueError: a setting differs, naming it,
            its option and both values.
    """
    if not path.exists():
        raise FileNotFoundError(f"{path.parent}: no run to resume (no {SETTINGS})")
    old = json.loads(path.read_text())
    # Runs made before strategies had names made the paper's decisions; batch runs made
    # before --adjust did not adjust.
    old.setdefault("strategy", "paper")
    if old.get("fidelity") == "batch":
        old.setdefault("adjust", False)
    if old.get("scenario_digest") != settings["scenario_digest"]:
        raise ValueError(
            f"{path.parent}: cannot resume: the run there was made with another scenario "
            f"(scenario_digest {old.get('scenario_digest')!r}, this one "
            f"{settings['scenario_digest']!r}): its file changed, or this version of the "
            "software gives scenarios other keys or defaults. Start a new run there with "
            "--overwrite, or in another --out"
        )
    again = "resume with the same setting, or start a new run with --overwrite or in another --out"
    for key, option in RESULT_SETTINGS.items():
        if old.get(key) != settings.get(key):
            raise ValueError(
                f"{path.parent}: cannot resume: the run there has {key} = {old.get(key)!r} "
                f"({option}), this one {settings.get(key)!r}; {again}"
            )
    before = old.get("trials")
    if isinstance(before, int) and trials < before:
        raise ValueError(
            f"{path.parent}: cannot resume: the run there has trials = {before} (--trials), "
            f"this one {trials}; a resumed run may go on to more trials, not fewer: resume "
            f"with --trials {before} or more"
        )


def check_trials(scenario: Scenario, trials: int, configs: Sequence[str]) -> None:
    """Refuse a trial count whose table would exceed :data:`MAX_TABLE_ROWS` rows.

    Raises:
        ValueError: naming the count, the table's rows and the largest count allowed.
    """
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    per_trial = len(configs) * max(len(planned_visits(scenario)), 1)
    if trials * per_trial > MAX_TABLE_ROWS:
        raise ValueError(
            f"--trials {trials}: the trial table would have {trials * per_trial} rows "
            f"({len(configs)} configuration(s) x {per_trial // len(configs)} planned "
            f"visit(s) a trial), more than the {MAX_TABLE_ROWS} a run holds (it keeps its "
            f"table in memory to sort and summarise it, about 2.5 kB a row): at most --trials "
            f"{MAX_TABLE_ROWS // per_trial} here"
        )


def trial_specs(
    scenario: Scenario,
    configs: Sequence[str],
    trials: int,
    master_seed: int,
    fidelity: str,
    strategy: str,
    done: set[tuple[str, int]] | frozenset[tuple[str, int]] = frozenset(),
) -> Iterator[TrialSpec]:
    """The trials of a run that ``done`` lacks, made one at a time as they are asked for:
    each configuration's trials 0 to ``trials`` - 1 in turn, configuration after
    configuration."""
    for config in configs:
        for i in range(trials):
            if (config, i) not in done:
                yield TrialSpec(scenario, config, i, trial_seed(master_seed, i), fidelity, strategy)


def run_montecarlo(
    scenario: Scenario,
    out_dir: str | Path,
    trials: int,
    *,
    fidelity: str = "batch",
    master_seed: int | None = None,
    budget: bool = False,
    workers: int = 1,
    engine: str = "local",
    ray_address: str | None = None,
    resume: bool = False,
    progress: Callable[[McProgress], None] | None = None,
    trial_fn: Callable[[TrialSpec], Any] = run_trial,
    strategy: str | None = None,
    overwrite: bool = False,
    chunk_size: int | None = None,
    adjust: bool = False,
    report: bool = True,
) -> list[dict[str, Any]]:
    """Run ``trials`` trials of ``scenario`` per configuration; returns the sorted table.

    Args:
        scenario: the scenario, with the noise of the real system.
        out_dir: where ``trials.csv`` and ``montecarlo.json`` go.
        trials: trials per configuration.
        fidelity: ``batch`` (default: the campaign's plan for many trials at once),
            ``geometric`` or ``render``.
        master_seed: the seed every trial's seed follows from (default: the scenario's).
        budget: also run each noise source alone (:mod:`twin.montecarlo.sources`).
        workers: processes (local) or CPUs of a new local Ray instance (ray).
        engine: ``local`` or ``ray``. ray_address: an existing Ray cluster's address.
        resume: continue the run in ``out_dir``, running only the trials its table lacks:
            the same scenario and :data:`RESULT_SETTINGS`, and as many trials or more
            (more: the run goes on to the new count).
        progress: called as the run starts (the trials already done) and as trials finish.
        trial_fn: what runs one trial (a picklable function; tests replace it).
        strategy: the campaign's strategy by name (default: the scenario's
            ``campaign.strategy``).
        overwrite: replace what an earlier run wrote in ``out_dir``.
        chunk_size: trials one array holds at the batch fidelity (default: the trials
            shared evenly among the workers, at most
            :data:`twin.montecarlo.batch_trials.DEFAULT_CHUNK_SIZE`).
        adjust: at the batch fidelity, also adjust each trial's whole network (the
            ``adjusted_*`` columns; on the paper's hall 13 trials/s instead of 100, the
            plan's recording aside). The geometric and render fidelities always adjust (as
            ``twin run`` does).
        report: write ``figures/`` and ``report.md`` beside the table and the summary (a
            caller that reads only the rows, a test say, need not draw them).

    Raises:
        ValueError: for bad counts (more than :data:`MAX_TABLE_ROWS` rows), an unknown
            strategy, or settings that differ from the run being resumed (fewer trials).
        twin.outputs.OutputError: ``out_dir`` cannot be used: it holds something else
            and neither ``resume`` (for a Monte-Carlo run) nor ``overwrite`` was given.
    """
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {', '.join(FIDELITIES)}, got {fidelity!r}")
    if chunk_size is not None and (fidelity != "batch" or chunk_size < 1):
        raise ValueError(
            f"chunk_size (trials one array holds) goes with the batch fidelity and must be at "
            f"least 1, got {chunk_size} at the {fidelity} fidelity"
        )
    configs = configurations(budget)
    check_trials(scenario, trials, configs)
    seed = scenario.seed if master_seed is None else check_seed(master_seed)
    chosen = strategy_name(scenario, strategy)
    settings = _settings(scenario, fidelity, chosen, seed, configs)
    if fidelity == "batch":
        check_batch_scenario(scenario)
        settings["batch_omits"] = list(BATCH_OMITS)
        settings["adjust"] = bool(adjust)
    if resume:
        # Checked before anything starts or is written.
        check_folder(Path(out_dir), "montecarlo", [*OUTPUTS, MANIFEST], resume=True)
        _check_resume(Path(out_dir) / SETTINGS, settings, trials)
    plan = record_plan(scenario, chosen) if fidelity == "batch" else None
    runner = make_engine(engine, workers, ray_address)
    try:
        folder = claim_folder(
            Path(out_dir), "montecarlo", OUTPUTS, settings, overwrite=overwrite, resume=resume
        )
        out = folder.path
        settings_path, table_path = out / SETTINGS, out / TABLE
        settings["trials"] = trials
        write_text_atomic(settings_path, json.dumps(settings, indent=2) + "\n")
        rows_per_trial = len(planned_visits(scenario))
        total = trials * len(configs)
        with TrialTable(table_path, rows_per_trial) as table:
            done0 = sum(1 for c, i in table.done if c in configs and i < trials)
            todo = trial_specs(scenario, configs, trials, seed, fidelity, chosen, table.done)
            t0 = time.perf_counter()
            if plan is not None:
                size = chunk_size or default_chunk_size(total - done0, workers)
                units: Iterator[Any] = chunks(plan, todo, size, adjust)
                fn: Callable[[Any], Any] = run_batch_chunk
            else:
                units, fn = todo, trial_fn
            if progress:
                progress(McProgress(done0, total, 0.0))
            n = 0
            for unit in runner.imap_unordered(fn, units):
                results = unit if isinstance(unit, list) else [unit]
                table.append(*(result.rows for result in results))
                n += len(results)
                if progress:
                    rate = n / max(time.perf_counter() - t0, 1e-9)
                    progress(McProgress(done0 + n, total, rate, results[-1].spec))
            elapsed = time.perf_counter() - t0
            rows = table.finish(configs)
    finally:
        runner.close()
    rows = [r for r in rows if r["config"] in configs and r["trial"] < trials]
    settings["trials_per_second"] = n / elapsed if n and elapsed > 0 else None
    settings["wall_time_s"] = elapsed
    write_outputs(rows, settings, out, report)
    folder.finished(trials=trials)
    return rows


def _finite_or_null(value: Any) -> Any:
    """``value`` with every NaN or infinite float replaced by None (JSON's null)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_null(v) for v in value]
    return value


def write_outputs(
    rows: list[dict[str, Any]], settings: dict[str, Any], out: Path, report: bool = True
) -> dict:
    """``summary.json``, ``figures/`` and ``report.md`` (the last two only with ``report``) of
    a finished table; returns the summary."""
    from twin.montecarlo.figures import write_figures
    from twin.montecarlo.report import write_report
    from twin.montecarlo.summary import summarise

    summary = summarise(rows, settings)
    text = json.dumps(_finite_or_null(summary), indent=2, allow_nan=False)
    write_text_atomic(out / SUMMARY, text + "\n")
    if report:
        figures = write_figures(rows, summary, out / "figures")
        write_report(summary, figures, out)
    return summary
