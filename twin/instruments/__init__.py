"""Instrument models: the total station, its inclination sensor, and the marker assembly.

Modules, one job each (pure numpy/scipy, shared by the simulated and the real instruments):

- :mod:`.total_station`: ``TotalStationSpec``, ``InclinometerSpec`` (Table I defaults), ``ARCSEC``.
- :mod:`.polar`: the measurement record, polar <-> Cartesian conversions and Jacobians.
- :mod:`.noise`: noise, output rounding, and the covariance they imply.
- :mod:`.aim`: automatic aim within the search cone, with a line-of-sight callback.
- :mod:`.tilt`: inclination readings and levelling.
- :mod:`.errors`: typed failures (``FailureReason`` and ``InstrumentError`` subclasses,
  including ``ConsistencyError``: measurements that fail their chi-square test).
- :mod:`.consistency`: chi-square consistency tests at a chosen false-alarm rate.
- :mod:`.shot`: one complete simulated shot, and a vectorised batch of shots.
- :mod:`.marker`, :mod:`.marker_pose`: the cube/LED assembly, its pose from three cubes,
  LED positions and covariance, and the chi-square of the cubes against the assembly,
  for one fit or over arrays of Monte Carlo trials.
"""
