"""The hardware-abstraction interface implemented on the MuJoCo world, at two fidelities.

:func:`build_sim_rig` returns a :class:`twin.hal.Rig` whose devices act on a
:class:`twin.sim.world.World`:

- ``render``: the bases drive in MuJoCo on wheel odometry, the cameras are rendered through
  their lens and sensor, and the LEDs are found in the images by on/off subtraction.
- ``geometric``: the bases are placed at their goals with a stopping error, the LEDs are
  projected through the true camera with the render fidelity's detection noise; MuJoCo
  ray casts still decide what the instrument and the cameras can see.

Both use the total station's measurement model (:mod:`twin.instruments`), with MuJoCo ray
casts for its line of sight, and both can inject faults (``[faults]`` in the scenario).
Given a recorder, the simulation records its own truth beside the readings
(:mod:`.truth`, :mod:`twin.truth`). Both pass :func:`twin.hal.check_rig`.
"""

from twin.sim.rig.build import FIDELITIES, SimRig, build_sim_rig
from twin.sim.rig.frames import WorldFrame

__all__ = ["FIDELITIES", "SimRig", "WorldFrame", "build_sim_rig"]
