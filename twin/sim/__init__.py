"""MuJoCo simulation of the twin: scene composition, robots, driving, cameras, rendering.

Importing this package first chooses the headless OpenGL backend (:mod:`twin.sim.gl`),
before anything imports mujoco. Modules (import what you need):

- :mod:`twin.sim.camera`: MuJoCo camera <-> :class:`calib.camera.TsaiCamera` conversion.
- :mod:`twin.sim.hall`: the space (floor, walls, obstacles, tilted floor patches).
- :mod:`twin.sim.people`: people walking through the space (moving distractors).
- :mod:`twin.sim.robots`: loading the robot models and attaching them to a scene.
- :mod:`twin.sim.scene`: composes a scenario into a MuJoCo model (:class:`mujoco.MjSpec`).
- :mod:`twin.sim.world`: :func:`build_world` compiles it into a :class:`World` that steps it
  and knows where everything truly is; :mod:`twin.sim.driving` moves the robots (commands,
  controllers, the wheel hold, odometry, collisions), :mod:`twin.sim.sensing` answers lines
  of sight and switches LEDs and lights.
- :mod:`twin.sim.controller`: go-to-pose controller with the Pioneers' speed limits.
- :mod:`twin.sim.odometry`: wheel odometry that drifts.
- :mod:`twin.sim.gl`: the headless OpenGL backend (EGL, else OSMesa).
- :mod:`twin.sim.render`: offscreen rendering of pinhole images.
- :mod:`twin.sim.lens`: lens distortion and supersampling by remapping a larger image.
- :mod:`twin.sim.sensor`: the image sensor (exposure, photon and read noise, bits, blur).
- :mod:`twin.sim.capture`: camera frames with their ground truth, and LED sequences.

The robots' dimensions, motion limits and odometry error model are plain data in
:mod:`twin.scenario.robots` (no MuJoCo).
"""

from twin.sim.gl import configure_headless

configure_headless()
