"""Cooperative positioning (CPS): solvers, covariance propagation and the step record.

- :mod:`.planar`: Rz, paper eq. (1) and its inverse.
- :mod:`.input_checks`: input checks, ``PoorGeometryWarning``, ``ConvergenceWarning``.
- :mod:`.pose`: ``ParentPose`` and ``CpsSolution``.
- :mod:`.closed_form`: the paper's two-child closed form (eq. 2) with covariance.
- :mod:`.wls`: generalised least squares for two or more children.
  Both raise ``InconsistentChildrenError`` when the children do not fit their world
  positions (chi-square test at ``false_alarm_rate``).
- :mod:`.propagation`: measured points (cubes, LEDs) to the world with the parent's error.
- :mod:`.observation`: ``ChildObservation`` (a child's cube centroid as measured; the
  marker fit rejects a wrong prism with ``InconsistentMarkerError``).
- :mod:`.sequence`: ``CpsSequence``, the joint estimate and the record of every step.
- :mod:`.leapfrog`: a pure-numpy straight leapfrog simulator and Monte Carlo.
- :mod:`.network`: a whole campaign's measurements as one network (stations, stands,
  control points, LED stops, cameras).
- :mod:`.adjustment`: the global adjustment of a network (sparse least squares) with its
  covariance.

Each estimator is written once, over arrays of T Monte Carlo trials (``*_batch``
functions, ``ParentPoseBatch``, ``CpsSolutionBatch``, ``ChildObservationBatch``,
``CpsBatch``); the one-trial forms (``solve_wls``, ``observe_child``, ``CpsSequence``) are
that code at T = 1, raising where it flags a trial.
"""
