"""The batch fidelity: the campaign's plan executed for many trials at once.

- :mod:`.plan`: :func:`record_plan`, the campaign as its strategy plays it without noise.
- :mod:`.execute`: :class:`BatchRun`, the plan for T trials, noise and estimates as arrays.
- :mod:`.estimators`: the campaign's estimators over trials; :class:`TrialByTrial` runs the
  scalar code on each trial in turn (the reference).
- :mod:`.vectorised`: :class:`Vectorised`, the same estimators as array code (the default).
"""
