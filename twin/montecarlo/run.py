"""A Monte-Carlo run: N trials of a scenario's campaign per noise configuration, written
to a trial table as they finish, then summarised.

``DIR/montecarlo.json`` holds what defines the run (scenario, fidelity, master seed,
configurations); ``--resume`` checks it and runs only the trials the table lacks.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.batch.plan import record_plan
from twin.campaign.strategies import strategy_for
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
from twin.outputs import claim_folder, write_text_atomic
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


def _check_resume(path: Path, settings: dict[str, Any]) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{path.parent}: no run to resume (no {SETTINGS})")
    old = json.loads(path.read_text())
    # Runs made before strategies had names made the paper's decisions.
    old.setdefault("strategy", "paper")
    if old.get("scenario_digest") != settings["scenario_digest"]:
        raise ValueError(
            f"{path.parent}: cannot resume: the run there was made with another scenario "
            f"(scenario_digest {old.get('scenario_digest')!r}, this one "
            f"{settings['scenario_digest']!r}): its file changed, or this version of the "
            "software gives scenarios other keys or defaults. Start a new run there with "
            "--overwrite, or in another --out"
        )
    for key in ("fidelity", "strategy", "master_seed", "configurations"):
        if old.get(key) != settings[key]:
            raise ValueError(
                f"{path.parent}: cannot resume: the run there has {key} = {old.get(key)!r}, "
                f"this one {settings[key]!r}"
            )


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
        resume: continue the run in ``out_dir`` (same scenario, fidelity, seed and
            configurations), running only the trials its table lacks.
        progress: called after each finished trial.
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

    Raises:
        ValueError: for bad counts, an unknown strategy, or settings that differ from the
            run being resumed.
        twin.outputs.OutputError: ``out_dir`` cannot be used: it holds something else
            and neither ``resume`` (for a Monte-Carlo run) nor ``overwrite`` was given.
    """
    if trials < 1:
        raise ValueError(f"trials must be at least 1, got {trials}")
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {', '.join(FIDELITIES)}, got {fidelity!r}")
    if chunk_size is not None and (fidelity != "batch" or chunk_size < 1):
        raise ValueError(
            f"chunk_size (trials one array holds) goes with the batch fidelity and must be at "
            f"least 1, got {chunk_size} at the {fidelity} fidelity"
        )
    seed = scenario.seed if master_seed is None else check_seed(master_seed)
    strategy_name = strategy_named_in(scenario, strategy)
    configs = configurations(budget)
    settings = _settings(scenario, fidelity, strategy_name, seed, configs)
    plan = None
    if fidelity == "batch":
        check_batch_scenario(scenario)
        plan = record_plan(scenario, strategy_name)
        settings["batch_omits"] = list(BATCH_OMITS)
        settings["adjust"] = bool(adjust)
    runner = make_engine(engine, workers, ray_address)
    try:
        folder = claim_folder(
            Path(out_dir), "montecarlo", OUTPUTS, settings, overwrite=overwrite, resume=resume
        )
        out = folder.path
        settings_path, table_path = out / SETTINGS, out / TABLE
        if resume:
            _check_resume(settings_path, settings)
        settings["trials"] = trials
        write_text_atomic(settings_path, json.dumps(settings, indent=2) + "\n")
        rows_per_trial = len(planned_visits(scenario))
        specs = [
            TrialSpec(scenario, config, i, trial_seed(seed, i), fidelity, strategy_name)
            for config in configs
            for i in range(trials)
        ]
        with TrialTable(table_path, rows_per_trial) as table:
            todo = [s for s in specs if (s.config, s.trial) not in table.done]
            done0 = len(specs) - len(todo)
            t0 = time.perf_counter()
            if plan is not None:
                size = chunk_size or default_chunk_size(len(todo), workers)
                units: list[Any] = list(chunks(plan, todo, size, adjust))
                fn: Callable[[Any], Any] = run_batch_chunk
            else:
                units, fn = todo, trial_fn
            n = 0
            for unit in runner.imap_unordered(fn, units):
                results = unit if isinstance(unit, list) else [unit]
                table.append(*(result.rows for result in results))
                n += len(results)
                if progress:
                    rate = n / max(time.perf_counter() - t0, 1e-9)
                    progress(McProgress(done0 + n, len(specs), rate, results[-1].spec))
            elapsed = time.perf_counter() - t0
            rows = table.finish(configs)
    finally:
        runner.close()
    wanted = {(s.config, s.trial) for s in specs}
    rows = [r for r in rows if (r["config"], r["trial"]) in wanted]
    settings["trials_per_second"] = len(todo) / elapsed if todo and elapsed > 0 else None
    settings["wall_time_s"] = elapsed
    write_outputs(rows, settings, out)
    folder.finished(trials=trials)
    return rows


def strategy_named_in(scenario: Scenario, name: str | None) -> str:
    """The strategy's name a run uses: ``name``, else the scenario's; checked to exist.

    Raises:
        ValueError: no strategy has that name.
    """
    return strategy_for(scenario, name).name


def _finite_or_null(value: Any) -> Any:
    """``value`` with every NaN or infinite float replaced by None (JSON's null)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_null(v) for v in value]
    return value


def write_outputs(rows: list[dict[str, Any]], settings: dict[str, Any], out: Path) -> dict:
    """``summary.json``, ``figures/`` and ``report.md`` of a finished table; returns the
    summary."""
    from twin.montecarlo.figures import write_figures
    from twin.montecarlo.report import write_report
    from twin.montecarlo.summary import summarise

    summary = summarise(rows, settings)
    text = json.dumps(_finite_or_null(summary), indent=2, allow_nan=False)
    write_text_atomic(out / SUMMARY, text + "\n")
    figures = write_figures(rows, summary, out / "figures")
    write_report(summary, figures, out)
    return summary
