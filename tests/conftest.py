"""The suite's collection: tests/rl (MaskablePPO through the environment, which needs torch
and sb3-contrib) is left out of ``pytest`` and ``make test``; ``make test-rl`` runs it in
.venv-rl, by naming the folder (``pytest tests/rl``)."""

collect_ignore = ["rl"]
