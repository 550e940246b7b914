"""Monte-Carlo error budgets: many trials of a scenario's campaign, summarised.

- :mod:`.seeds`: each trial's seed from the master seed and its index.
- :mod:`.sources`: the noise sources of a budget, and a scenario with one source alone.
- :mod:`.trial`: one trial, as rows of the trial table (one per planned camera visit).
- :mod:`.prediction`: what the covariance propagation predicts, read from a run's log.
- :mod:`.table`: the trial table (CSV), appended as trials finish, resumable.
- :mod:`.engines`: where trials run: a local process pool or Ray.
- :mod:`.run`: :func:`run_montecarlo`, the whole run.
- :mod:`.summary`, :mod:`.figures`, :mod:`.report`: what the table says.

Importing this package first chooses the headless OpenGL backend as ``twin run`` does
(:mod:`twin.sim.gl`, before anything here imports mujoco): the command and every worker
process (a worker imports this package to run its trials) render at the render fidelity
without ``MUJOCO_GL`` set.
"""

import twin.sim  # noqa: F401  (first: chooses the OpenGL backend before mujoco is imported)
from twin.montecarlo.run import McProgress, run_montecarlo
from twin.montecarlo.seeds import trial_seed
from twin.montecarlo.sources import ALL, SOURCES, isolate
from twin.montecarlo.trial import COLUMNS, TrialResult, TrialSpec, run_trial

__all__ = [
    "ALL",
    "COLUMNS",
    "SOURCES",
    "McProgress",
    "TrialResult",
    "TrialSpec",
    "isolate",
    "run_montecarlo",
    "run_trial",
    "trial_seed",
]
