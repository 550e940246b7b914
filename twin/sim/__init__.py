"""MuJoCo simulation of the twin: scene composition, robots, driving, cameras, rendering.

Modules (import what you need; this package imports nothing on its own):

- :mod:`twin.sim.camera`: MuJoCo camera <-> :class:`calib.camera.TsaiCamera` conversion.
- :mod:`twin.sim.hall`: the space (floor, walls, obstacles, tilted floor patches).
- :mod:`twin.sim.robots`: loading the robot models and attaching them to a scene.
- :mod:`twin.sim.scene`: :func:`build_world` composes a scenario into a :class:`World`.
- :mod:`twin.sim.drive`: go-to-pose controller with the Pioneers' speed limits.
- :mod:`twin.sim.odometry`: wheel odometry that drifts.
- :mod:`twin.sim.render`: offscreen rendering of the fixed cameras.

The robots' dimensions, motion limits and odometry error model are plain data in
:mod:`twin.scenario.robots` (no MuJoCo).
"""
