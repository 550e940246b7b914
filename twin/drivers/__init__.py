"""Real hardware behind :mod:`twin.hal`: the total station (Leica GeoCOM), the Pioneer bases
and their LEDs (ARCOS), the cameras (OpenCV, GenICam), the wall clock; and the rig file
that says which device is where (:mod:`.rig_file`).

The campaign never imports this package: a rig is built here, from a rig file, and
handed in, as the simulated rig is built in :mod:`twin.sim.rig`.
"""
