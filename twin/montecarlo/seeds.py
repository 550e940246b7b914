"""Seeds of Monte-Carlo trials: each trial's seed follows from the master seed and its
index alone, so any trial can be run again on its own."""

from __future__ import annotations

import numpy as np

TRIAL_STREAM = 7
"""Spawn key that separates trial seeds from the other streams drawn from a master seed."""


def trial_seed(master_seed: int, trial: int) -> int:
    """The root seed of trial ``trial`` (0-based) of a run with ``master_seed``.

    The same pair always gives the same seed, whatever else the run holds; different
    trials get independent streams (NumPy's ``SeedSequence`` spawn keys).

    Raises:
        ValueError: for a negative master seed or trial index.
    """
    if master_seed < 0 or trial < 0:
        raise ValueError(
            f"seeds and trial indices must be non-negative, got {master_seed} and {trial}"
        )
    seq = np.random.SeedSequence(int(master_seed), spawn_key=(TRIAL_STREAM, int(trial)))
    return int(seq.generate_state(1, dtype=np.uint32)[0])
