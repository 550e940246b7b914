"""Cooperative positioning (CPS): solvers, covariance propagation and the step record.

Each estimator is written once, over arrays of T trials; what one trial's data make it
fail is a per-trial flag. Its one-trial form (the unsuffixed name) runs it at T = 1 and
raises or warns where it flags.

- :mod:`.planar`: Rz, paper eq. (1) and its inverse.
- :mod:`.input_checks`: input checks, ``PoorGeometryWarning``, ``ConvergenceWarning``;
  the per-trial flags of poor geometry.
- :mod:`.pose`: ``ParentPose`` and ``CpsSolution``; ``ParentPoseBatch`` and
  ``CpsSolutionBatch`` over T trials.
- :mod:`.closed_form`: the paper's two-child closed form (eq. 2) with covariance.
- :mod:`.wls`: generalised least squares for two or more children.
  Both raise ``InconsistentChildrenError`` when the children do not fit their world
  positions (chi-square test at ``false_alarm_rate``).
- :mod:`.propagation`: measured points (cubes, LEDs) to the world with the parent's error.
- :mod:`.observation`: ``ChildObservation`` (a child's cube centroid as measured; the
  marker fit rejects a wrong prism with ``InconsistentMarkerError``) and
  ``ChildObservationBatch`` over T trials.
- :mod:`.joint_state`: ``CpsBatch``, the joint estimates of T trials and their two
  kinds of step.
- :mod:`.sequence`: ``CpsSequence``, one trial with the record of every step.
- :mod:`.leapfrog`: a pure-numpy straight leapfrog simulator and Monte Carlo.
- :mod:`.network`: a whole campaign's measurements as one network (stations, stands,
  control points, LED stops, cameras).
- :mod:`.adjustment`: the global adjustment of a network (sparse least squares) with its
  covariance.
"""
