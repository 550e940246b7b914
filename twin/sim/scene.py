"""Composing a scenario into a MuJoCo model (:class:`mujoco.MjSpec`).

The scene is built in code: the space (:mod:`twin.sim.hall`), one attached device per
robot (prefix ``NAME/``), one fixed camera per scenario camera (its name as given; where
``faults.moved_cameras`` moves it, at its moved pose) and the people walking by. The
MuJoCo world frame *is* the twin's world frame W (the parent's instrument frame at its
start, z up); the floor lies at ``scenario.space.floor_z``.
:class:`twin.sim.world.World` runs the compiled model.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco

from twin.instruments.marker import MarkerAssembly
from twin.scenario.schema import Scenario
from twin.sim.camera import add_camera
from twin.sim.hall import build_space
from twin.sim.people import add_person
from twin.sim.robots import attach_robot

NEAR_CLIP = 0.1
"""Distance of the cameras' near clipping plane, m: nothing a camera must see is nearer."""

NOSLIP_ITERATIONS = 2
"""Iterations of MuJoCo's no-slip solver: without it soft contacts let a parked robot slide
under a sustained sideways load (a wheel resting on the edge of a floor patch)."""


def build_spec(
    scenario: Scenario, markers: Mapping[str, MarkerAssembly] | None = None
) -> mujoco.MjSpec:
    """The scene of ``scenario`` as an uncompiled :class:`mujoco.MjSpec`.

    Args:
        markers: the built marker assembly of some children by name, where it differs
            from the scenario's ``[marker]`` geometry (a surveying error).
    """
    spec = mujoco.MjSpec()
    spec.modelname = scenario.name
    spec.compiler.degree = False
    spec.option.timestep = scenario.sim.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.noslip_iterations = NOSLIP_ITERATIONS
    max_w = max(c.image_size[0] for c in scenario.cameras)
    max_h = max(c.image_size[1] for c in scenario.cameras)
    spec.visual.global_.offwidth = max(640, max_w)
    spec.visual.global_.offheight = max(480, max_h)
    # MuJoCo's clipping planes are relative to the model's extent: the near one is held at
    # NEAR_CLIP m whatever the space's size (a 500 m site would clip 5 m at 1 %).
    extent = float(max(scenario.space.size))
    spec.stat.extent = extent
    spec.visual.map.znear = NEAR_CLIP / extent
    spec.visual.map.zfar = 200.0
    build_space(spec, scenario.space)
    marker = scenario.marker.assembly()
    for robot in scenario.robots.all:
        mine = (markers or {}).get(robot.name, marker)
        attach_robot(spec, robot, scenario.space.floor_z, mine)
    for cam in scenario.cameras:
        moved = scenario.faults.moved_camera(cam.name)
        pose = cam.tsai() if moved is None else moved.moved(cam.tsai())
        add_camera(spec.worldbody, cam.name, pose)
    for person in scenario.people:
        add_person(spec, person, scenario.space.floor_z)
    return spec
