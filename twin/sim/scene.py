"""Composing a scenario into a MuJoCo world, and the :class:`World` that runs it.

The scene is built in code: the space (:mod:`twin.sim.hall`), one attached device per
robot (prefix ``NAME/``), and one fixed camera per scenario camera (its name as given).
The MuJoCo world frame *is* the twin's world frame W (the parent's instrument frame at
its start, z up); the floor lies at ``scenario.space.floor_z``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from twin.instruments.marker import MarkerAssembly
from twin.scenario.schema import Scenario
from twin.sim.camera import add_camera, tsai_from_model
from twin.sim.drive import DriveController, DriveTolerance
from twin.sim.hall import SPACE_GROUP, build_space
from twin.sim.odometry import WheelOdometry
from twin.sim.people import add_person, move_people
from twin.sim.robots import N_CUBES, N_LEDS, RobotHandle, attach_robot

# Stream of numpy.random.SeedSequence reserved for odometry errors.
ODOMETRY_STREAM = 1

# LED appearance when lit (the "off" state is the material in the MJCF file): bright
# enough to saturate every channel, so a lit LED is a uniform disc without shading.
LED_ON_RGBA = (1.0, 0.35, 0.25, 1.0)
LED_ON_EMISSION = 5.0

# A robot touching the same geom again within this many control periods of their last
# contact is the same collision (contacts flicker while a robot pushes against something).
COLLISION_DEBOUNCE_TICKS = 25

NOSLIP_ITERATIONS = 2
"""Iterations of MuJoCo's no-slip solver: without it soft contacts let a parked robot slide
under a sustained sideways load (a wheel resting on the edge of a floor patch)."""

HOLD_GAIN = 10.0
"""Gain of the wheels' position hold at rest, 1/s: a stopped robot's motor controller
commands each side's wheels the speed ``-HOLD_GAIN * (side's mean angle - its angle at
rest)``, as the Pioneers' controllers hold their wheels at zero speed with an integral
term. Without it the wheels of a parked robot roll freely against their speed servos'
damping: a P3-DX child whose wheels rested on the 1.5 mm edge of a tilted floor patch
rolled 12-20 mm off it in 30 s, enough for the parent's next CPS fix to fail its
consistency test."""

FELL_OVER_TILT = np.radians(30.0)
"""A robot whose body leans further than this from the vertical has fallen over, rad."""

# Most casts of one ray that may step past geoms of the robot it ignores.
MAX_RAY_RECASTS = 64

# Geom groups that block lines of sight: the space (0) and the robots' visual geoms (2).
SIGHT_GROUPS = np.array([1, 0, 1, 0, 0, 0], dtype=np.uint8)


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
    spec.visual.map.znear = 0.01
    spec.visual.map.zfar = 200.0
    spec.stat.extent = float(max(scenario.space.size))
    build_space(spec, scenario.space)
    marker = scenario.marker.assembly()
    for robot in scenario.robots.all:
        mine = (markers or {}).get(robot.name, marker)
        attach_robot(spec, robot, scenario.space.floor_z, mine)
    for cam in scenario.cameras:
        add_camera(spec.worldbody, cam.name, cam.tsai())
    for person in scenario.people:
        add_person(spec, person, scenario.space.floor_z)
    return spec


@dataclass(frozen=True)
class Collision:
    """A robot's chassis touching a wall, an obstacle or another robot.

    Attributes:
        time: simulation time when the contact was first seen, s.
        robot: the robot's name.
        other: name of the geom it touched (e.g. ``wall_north``, ``pillar``, ``child2/chassis``).
        position: (3,) contact point in the world frame, m.
    """

    time: float
    robot: str
    other: str
    position: NDArray[np.float64] = field(repr=False)


@dataclass(frozen=True)
class DriveResult:
    """Outcome of :meth:`World.drive_to`.

    Attributes:
        robot: the robot's name.
        status: ``reached``, ``collision``, ``fell_over`` or ``timeout``.
        pose: (3,) true final pose (x, y, yaw), m and rad.
        position_error: distance from the goal position, m (true pose).
        duration: simulated time taken, s.
        collisions: the collisions of this robot during the drive.
    """

    robot: str
    status: str
    pose: NDArray[np.float64]
    position_error: float
    duration: float
    collisions: tuple[Collision, ...]

    @property
    def reached(self) -> bool:
        """Whether the controller reported the goal reached."""
        return self.status == "reached"


class World:
    """A scenario's MuJoCo model and data, with robots, odometry, LEDs and cameras.

    Args:
        scenario: a validated scenario.
        control_period: period of the drive controllers and odometry updates, s.
        markers: the built marker assembly of some children (:func:`build_spec`).

    Attributes:
        scenario, spec, model, data: the scenario and its MuJoCo objects.
        robots: handle of each robot by name (``parent``, ``child1``...).
        odometry: wheel odometry of each robot by name.
        collisions: every collision seen so far, in time order.
    """

    def __init__(
        self,
        scenario: Scenario,
        control_period: float = 0.02,
        markers: Mapping[str, MarkerAssembly] | None = None,
    ) -> None:
        self.scenario = scenario
        self.spec = build_spec(scenario, markers)
        self.model = self.spec.compile()
        self._ids: dict[tuple[mujoco.mjtObj, str], int] = {}  # ids by (kind, name)
        self.data = mujoco.MjData(self.model)
        self.substeps = max(1, round(control_period / self.model.opt.timestep))
        self.control_period = self.substeps * self.model.opt.timestep
        self.robots = {
            r.name: RobotHandle.from_model(self.model, r.name, r.platform)
            for r in scenario.robots.all
        }
        self._chassis_robot = {h.chassis: h.name for h in self.robots.values()}
        self._is_chassis = np.zeros(self.model.ngeom, dtype=bool)
        self._is_chassis[list(self._chassis_robot)] = True
        self._led_off = {}
        for child in scenario.robots.children:
            for k in range(N_LEDS):
                mid = self._id(mujoco.mjtObj.mjOBJ_MATERIAL, f"{child.name}/led{k}")
                self._led_off[mid] = (
                    self.model.mat_rgba[mid].copy(),
                    float(self.model.mat_emission[mid]),
                )
        # The lights at level 1: each light's diffuse and specular, the headlight's.
        self._light_base = (
            self.model.light_diffuse.copy(),
            self.model.light_specular.copy(),
            np.array(self.model.vis.headlight.ambient, dtype=float),
            np.array(self.model.vis.headlight.diffuse, dtype=float),
        )
        self.reset()

    # -- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the start poses, time 0, LEDs off, odometry re-seeded from the scenario."""
        mujoco.mj_resetData(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        seeds = np.random.SeedSequence(self.scenario.seed, spawn_key=(ODOMETRY_STREAM,))
        spec = self.scenario.noise.odometry.spec()
        self.odometry = {}
        for (name, handle), seed in zip(
            self.robots.items(), seeds.spawn(len(self.robots)), strict=True
        ):
            self.odometry[name] = WheelOdometry(
                handle.platform.wheel_radius,
                handle.platform.effective_track,
                spec,
                np.random.default_rng(seed),
                pose=handle.pose(self.data),
            )
        self._wheels = {n: h.wheel_angles(self.data) for n, h in self.robots.items()}
        self._held: dict[str, NDArray[np.float64]] = {}  # wheel angles held at rest, by robot
        self._controllers: dict[str, DriveController] = {}
        self._pose_source: dict[str, str] = {}
        self._last_contact: dict[tuple[str, int], int] = {}
        self._tick = 0
        self._target = {n: (0.0, 0.0) for n in self.robots}
        self._command = {n: (0.0, 0.0) for n in self.robots}
        self.collisions: list[Collision] = []
        for mid, (rgba, emission) in self._led_off.items():
            self.model.mat_rgba[mid] = rgba
            self.model.mat_emission[mid] = emission
        self.set_light_level(1.0)
        self._move_people()

    def _move_people(self) -> None:
        if self.scenario.people:
            move_people(self.model, self.data, self.scenario.people, self.scenario.space.floor_z)
            mujoco.mj_kinematics(self.model, self.data)

    def place(
        self,
        robot: str,
        xy: ArrayLike,
        yaw: float = 0.0,
        settle: float = 0.1,
        hold_others: bool = False,
    ) -> None:
        """Put a robot at a pose on the floor at once (no driving), at rest.

        Odometry is reset to the new pose, a running drive is cancelled, and the world is
        stepped ``settle`` seconds so the robot rests on its wheels.

        Args:
            robot: the robot's name.
            xy: (2,) position of the body origin, m.
            yaw: heading, rad.
            settle: simulated seconds to step afterwards (0: none).
            hold_others: put the other robots back exactly where they were after the
                settling (their resting pose does not creep by micrometres).
        """
        h = self.robots[robot]
        p = np.asarray(xy, dtype=float).reshape(2)
        self.stop(robot)
        q = self.data.qpos
        q[h.qpos : h.qpos + 2] = p
        q[h.qpos + 2] = self.model.qpos0[h.qpos + 2]
        q[h.qpos + 3 : h.qpos + 7] = [np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)]
        self.data.qvel[h.qvel : h.qvel + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)
        held = [
            (o, self.data.qpos[o.qpos : o.qpos + 7].copy())
            for o in self.robots.values()
            if hold_others and o.name != robot
        ]
        if settle > 0:
            self.run(settle)
        if held:
            for o, qpos in held:
                self.data.qpos[o.qpos : o.qpos + 7] = qpos
                self.data.qvel[o.qvel : o.qvel + 6] = 0.0
            mujoco.mj_forward(self.model, self.data)
        self.odometry[robot].reset(h.pose(self.data))
        self._wheels[robot] = h.wheel_angles(self.data)
        self._held.pop(robot, None)

    # -- lights ------------------------------------------------------------------------------
    @property
    def light_level(self) -> float:
        """Level of all lights relative to the scenario's, 1 at the start."""
        return self._light_level

    def set_light_level(self, level: float) -> None:
        """Scale every light (the overhead lights and the headlight's ambient and diffuse
        parts) to ``level`` times the scenario's: a flickering or dimming light."""
        if not (np.isfinite(level) and level >= 0.0):
            raise ValueError(f"the light level must be finite and >= 0, got {level}")
        diffuse, specular, ambient, head = self._light_base
        self.model.light_diffuse[:] = level * diffuse
        self.model.light_specular[:] = level * specular
        self.model.vis.headlight.ambient[:] = level * ambient
        self.model.vis.headlight.diffuse[:] = level * head
        self._light_level = float(level)

    @property
    def time(self) -> float:
        """Simulation time, s."""
        return float(self.data.time)

    def _id(self, kind: mujoco.mjtObj, name: str) -> int:
        key = (kind, name)
        i = self._ids.get(key)
        if i is None:
            i = mujoco.mj_name2id(self.model, kind, name)
            if i < 0:
                kind_name = kind.name.removeprefix("mjOBJ_").lower()
                raise KeyError(f"the model has no {kind_name} {name!r}")
            self._ids[key] = i
        return i

    # -- stepping ----------------------------------------------------------------------------
    def step(self, ticks: int = 1) -> list[Collision]:
        """Advance ``ticks`` control periods: controllers, physics, odometry, collisions.

        Returns:
            The collisions that began during these ticks.
        """
        new: list[Collision] = []
        for _ in range(ticks):
            self._tick += 1
            self._control()
            self._apply_commands()
            if self.scenario.people:
                move_people(
                    self.model, self.data, self.scenario.people, self.scenario.space.floor_z
                )
            mujoco.mj_step(self.model, self.data, nstep=self.substeps)
            self._update_odometry()
            new += self._detect_collisions()
        return new

    def run(self, seconds: float) -> list[Collision]:
        """Advance about ``seconds`` of simulated time (whole control periods)."""
        return self.step(max(1, round(seconds / self.control_period)))

    def warnings(self) -> dict[str, int]:
        """MuJoCo warnings raised so far, by name (empty when there were none)."""
        return {
            mujoco.mjtWarning(i).name: int(w.number)
            for i, w in enumerate(self.data.warning)
            if w.number > 0
        }

    # -- driving -----------------------------------------------------------------------------
    def set_body_velocity(self, robot: str, v: float, w: float) -> None:
        """Command a forward speed (m/s) and a yaw rate (rad/s).

        The command is clipped to the robot's speed and turn-rate limits and reached at
        its acceleration limits, from the next :meth:`step` on: each control period the
        applied (v, w) moves towards it by at most ``max_accel`` and ``max_yaw_accel``
        times the period. The applied (v, w) becomes wheel speeds through the robot's
        ``command_track``.
        """
        p = self.robots[robot].platform
        self._target[robot] = (
            float(np.clip(v, -p.max_speed, p.max_speed)),
            float(np.clip(w, -p.max_yaw_rate, p.max_yaw_rate)),
        )

    def set_wheel_speeds(self, robot: str, left: float, right: float) -> None:
        """Command the wheel speeds of each side, rad/s: the same as the (v, w) they
        make through the robot's ``command_track``, with the same limits (see
        :meth:`set_body_velocity`)."""
        p = self.robots[robot].platform
        r = p.wheel_radius
        self.set_body_velocity(
            robot, 0.5 * r * (left + right), r * (right - left) / p.command_track
        )

    def body_velocity_command(self, robot: str) -> tuple[float, float]:
        """The (v, w) applied to the robot's wheels in the last control period."""
        return self._command[robot]

    def _apply_commands(self) -> None:
        dt = self.control_period
        for name, h in self.robots.items():
            p = h.platform
            v0, w0 = self._command[name]
            vt, wt = self._target[name]
            # The controllers ramp by exactly these steps: allow for rounding.
            v = _ramp(v0, vt, p.max_accel * dt * (1.0 + 1e-9))
            w = _ramp(w0, wt, p.max_yaw_accel * dt * (1.0 + 1e-9))
            self._command[name] = (v, w)
            if v == 0.0 and w == 0.0 and vt == 0.0 and wt == 0.0:
                self._hold(h)
                continue
            self._held.pop(name, None)
            half = 0.5 * p.command_track
            self._set_ctrl(h, (v - w * half) / p.wheel_radius, (v + w * half) / p.wheel_radius)

    def _hold(self, h: RobotHandle) -> None:
        """At rest: command each side's wheels back to the mean angle the side had when the
        robot stopped (one command per side, as the motor controller drives them: holding
        the wheels of one side each to its own angle would set them against each other
        through the floor, and a skid-steered robot would slowly turn)."""
        angles = np.array(h.wheel_angles(self.data))
        held = self._held.setdefault(h.name, angles)
        left, right = -HOLD_GAIN * (angles - held)
        self._set_ctrl(h, float(left), float(right))

    def _set_ctrl(self, h: RobotHandle, left: float, right: float) -> None:
        for a in h.left_act:
            self.data.ctrl[a] = left
        for a in h.right_act:
            self.data.ctrl[a] = right

    def drive(
        self,
        robot: str,
        goal_xy: ArrayLike,
        goal_yaw: float | None = None,
        pose_source: str = "truth",
        tolerance: DriveTolerance | None = None,
    ) -> DriveController:
        """Start driving ``robot`` to a goal; :meth:`step` then runs its controller.

        Args:
            robot: the robot's name.
            goal_xy: (x, y) goal of the body origin, m.
            goal_yaw: goal heading, rad (None: keep the arrival heading).
            pose_source: ``truth`` (the simulator's pose, standing in for an external
                positioning system such as CPS) or ``odometry`` (dead reckoning).
            tolerance: when the goal counts as reached.
        """
        if pose_source not in ("truth", "odometry"):
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {pose_source!r}")
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        ctl = DriveController(self.robots[robot].platform, (g[0], g[1]), goal_yaw, tolerance)
        self._controllers[robot] = ctl
        self._pose_source[robot] = pose_source
        return ctl

    def stop(self, robot: str) -> None:
        """Cancel the robot's goal and stop its wheels at once (an emergency stop: the
        acceleration limit does not apply)."""
        self._controllers.pop(robot, None)
        self._target[robot] = self._command[robot] = (0.0, 0.0)
        self._set_ctrl(self.robots[robot], 0.0, 0.0)

    def moving(self) -> list[str]:
        """Names of the robots that have a goal not yet reached."""
        return [n for n, c in self._controllers.items() if not c.done]

    def drive_to(
        self,
        robot: str,
        goal_xy: ArrayLike,
        goal_yaw: float | None = None,
        timeout: float | None = None,
        pose_source: str = "truth",
        tolerance: DriveTolerance | None = None,
    ) -> DriveResult:
        """Drive ``robot`` to a goal and wait until it stops, collides, falls over or times out.

        The other robots keep their current commands. On a collision the robot is stopped.

        Args:
            timeout: simulated seconds allowed (default: three times the straight-line
                travel time at top speed, plus 10 s).
        """
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        h = self.robots[robot]
        if timeout is None:
            dist = float(np.linalg.norm(g - h.pose(self.data)[:2]))
            timeout = 3.0 * dist / h.platform.max_speed + 10.0
        ctl = self.drive(robot, g, goal_yaw, pose_source, tolerance)
        t0 = self.time
        mine: list[Collision] = []
        status = "timeout"
        while self.time - t0 < timeout:
            mine += [c for c in self.step() if c.robot == robot]
            if mine:
                self.stop(robot)
                status = "collision"
                break
            if h.tilt(self.data) > FELL_OVER_TILT:
                self.stop(robot)
                status = "fell_over"
                break
            if ctl.done:
                status = "reached"
                break
        self.stop(robot)
        pose = h.pose(self.data)
        return DriveResult(
            robot=robot,
            status=status,
            pose=pose,
            position_error=float(np.linalg.norm(pose[:2] - g)),
            duration=self.time - t0,
            collisions=tuple(mine),
        )

    def _control(self) -> None:
        for name, ctl in self._controllers.items():
            if ctl.done:
                self.set_body_velocity(name, 0.0, 0.0)
                continue
            if self._pose_source[name] == "truth":
                pose = self.robots[name].pose(self.data)
            else:
                pose = self.odometry[name].pose
            v, w = ctl.update((pose[0], pose[1], pose[2]), self.control_period)
            self.set_body_velocity(name, v, w)

    def _update_odometry(self) -> None:
        for name, h in self.robots.items():
            left, right = h.wheel_angles(self.data)
            l0, r0 = self._wheels[name]
            self.odometry[name].update(left - l0, right - r0)
            self._wheels[name] = (left, right)

    def _detect_collisions(self) -> list[Collision]:
        """Contacts of a chassis with anything; a (robot, geom) pair counts as a new
        collision unless it was in contact within the last ``COLLISION_DEBOUNCE_TICKS``."""
        n = self.data.ncon
        new: list[Collision] = []
        if n:
            g1 = self.data.contact.geom1[:n]
            g2 = self.data.contact.geom2[:n]
            seen: set[tuple[str, int]] = set()
            for k in np.flatnonzero(self._is_chassis[g1] | self._is_chassis[g2]):
                a, b = int(g1[k]), int(g2[k])
                for mine, other in ((a, b), (b, a)):
                    if not self._is_chassis[mine]:
                        continue
                    key = (self._chassis_robot[mine], other)
                    if key in seen:
                        continue
                    seen.add(key)
                    last = self._last_contact.get(key)
                    self._last_contact[key] = self._tick
                    if last is not None and self._tick - last <= COLLISION_DEBOUNCE_TICKS:
                        continue
                    name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, other)
                    pos = self.data.contact.pos[k].copy()
                    new.append(Collision(self.time, key[0], name or f"geom{other}", pos))
        self.collisions += new
        return new

    # -- reading the state -------------------------------------------------------------------
    def robot_pose(self, robot: str) -> NDArray[np.float64]:
        """(3,) true planar pose (x, y, yaw) of the robot's body origin, m and rad."""
        return self.robots[robot].pose(self.data)

    def body_pose(self, robot: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True pose of the robot's base body: (3,) position (m) and (3, 3) body-to-world."""
        b = self.robots[robot].body
        return self.data.xpos[b].copy(), self.data.xmat[b].reshape(3, 3).copy()

    def site_pose(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True pose of a site by full name (e.g. ``parent/instrument``): (3,) position, m,
        and (3, 3) site-to-world rotation."""
        s = self._id(mujoco.mjtObj.mjOBJ_SITE, name)
        return self.data.site_xpos[s].copy(), self.data.site_xmat[s].reshape(3, 3).copy()

    def instrument_pose(self, robot: str = "parent") -> tuple[NDArray, NDArray]:
        """True pose of the total station's origin (site ``ROBOT/instrument``)."""
        return self.site_pose(f"{robot}/instrument")

    def tilt(self, robot: str = "parent") -> NDArray[np.float64]:
        """(2,) true tilt of the robot's body: rotation about its x and y axes, rad
        (what a perfect two-axis inclination sensor on it reads)."""
        _, r = self.body_pose(robot)
        up = r.T @ np.array([0.0, 0.0, 1.0])  # world z in body axes
        return np.array([np.arctan2(up[1], up[2]), -np.arctan2(up[0], up[2])])

    def marker_points(self, child: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True world positions of a child's corner cubes (3, 3) and LEDs (4, 3), m."""
        cubes, leds = self._marker_sites(child)
        return self.data.site_xpos[cubes], self.data.site_xpos[leds]

    def _marker_sites(self, child: str) -> tuple[list[int], list[int]]:
        """Site ids of a child's corner cubes and LEDs."""
        site = mujoco.mjtObj.mjOBJ_SITE
        return (
            [self._id(site, f"{child}/cube{k}") for k in range(N_CUBES)],
            [self._id(site, f"{child}/led{k}") for k in range(N_LEDS)],
        )

    # -- LEDs, cameras, sight ----------------------------------------------------------------
    def set_leds(self, child: str, on: bool | Sequence[bool]) -> None:
        """Switch a child's LEDs: one flag for all four, or a flag per LED (index 0 lowest
        in the default geometry). Changes the LED materials' colour and emission."""
        flags = [bool(on)] * N_LEDS if isinstance(on, bool | np.bool_) else [bool(f) for f in on]
        if len(flags) != N_LEDS:
            raise ValueError(f"give one flag or {N_LEDS} flags for the LEDs, got {len(flags)}")
        for k, flag in enumerate(flags):
            mid = self._id(mujoco.mjtObj.mjOBJ_MATERIAL, f"{child}/led{k}")
            rgba, emission = self._led_off[mid]
            self.model.mat_rgba[mid] = LED_ON_RGBA if flag else rgba
            self.model.mat_emission[mid] = LED_ON_EMISSION if flag else emission

    def leds_on(self, child: str) -> list[bool]:
        """Which of a child's LEDs are lit."""
        out = []
        for k in range(N_LEDS):
            mid = self._id(mujoco.mjtObj.mjOBJ_MATERIAL, f"{child}/led{k}")
            out.append(bool(self.model.mat_emission[mid] > 0.5 * LED_ON_EMISSION))
        return out

    @property
    def camera_names(self) -> list[str]:
        """Names of the fixed cameras, in scenario order."""
        return [c.name for c in self.scenario.cameras]

    def camera(self, name: str) -> TsaiCamera | OpenCVCamera:
        """A fixed camera read back from the model (pose in W, OpenCV pixels), with the
        scenario's lens distortion (which MuJoCo does not render; :mod:`twin.sim.capture`
        applies it): a :class:`TsaiCamera` with kappa1, or an :class:`OpenCVCamera` when
        the scenario gives OpenCV coefficients. The ground truth of the camera's images."""
        cfg = self.scenario.camera(name)
        cam = tsai_from_model(self.model, self.data, name, cfg.kappa1)
        if cfg.opencv_distortion is None:
            return cam
        k = np.array([[cam.sx * cam.f, 0.0, cam.cx], [0.0, cam.f, cam.cy], [0.0, 0.0, 1.0]])
        return OpenCVCamera(
            k, np.asarray(cfg.opencv_distortion), cam.world2cam_r, cam.world2cam_t, cam.image_size
        )

    def ray(
        self, origin: ArrayLike, direction: ArrayLike, exclude_robot: str | None = None
    ) -> tuple[float, str | None]:
        """Cast a ray against the space and the robots' visible geoms.

        Args:
            origin: (3,) start, m. direction: (3,) direction (any length).
            exclude_robot: a robot whose geoms are all ignored (e.g. the one looking).

        Returns:
            (distance along the unit direction in m, name of the geom hit), or
            (inf, None) if nothing is hit.
        """
        o = np.asarray(origin, dtype=float).reshape(3)
        d = np.asarray(direction, dtype=float).reshape(3)
        dist, g = self._cast(o, d / np.linalg.norm(d), exclude_robot)
        if g < 0:
            return dist, None
        return dist, mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g)

    def _cast(self, origin: NDArray, unit: NDArray, exclude_robot: str | None) -> tuple[float, int]:
        """:meth:`ray` from (3,) ``origin`` along a (3,) unit direction: (distance m, geom
        id), or (inf, -1) if nothing is hit."""
        skip = self.robots[exclude_robot].geoms if exclude_robot else frozenset()
        body = self.robots[exclude_robot].body if exclude_robot else -1
        gid = np.array([-1], dtype=np.int32)
        start, travelled = origin, 0.0
        # mj_ray ignores one body only: step past any hit on the excluded robot's other
        # bodies (its wheels, say) and cast again from there.
        for _ in range(MAX_RAY_RECASTS):
            dist = mujoco.mj_ray(self.model, self.data, start, unit, SIGHT_GROUPS, 1, body, gid)
            if dist < 0:
                return float("inf"), -1
            g = int(gid[0])
            if g not in skip:
                return travelled + float(dist), g
            step = float(dist) + 1e-6
            travelled += step
            start = start + step * unit
            body = int(self.model.geom_bodyid[g])
        raise RuntimeError(f"ray from {origin} kept hitting robot {exclude_robot!r}")

    def line_of_sight(
        self,
        p_from: ArrayLike,
        p_to: ArrayLike,
        exclude_robot: str | None = None,
        tolerance: float = 0.05,
    ) -> bool:
        """Whether nothing blocks the segment from ``p_from`` to ``p_to`` (m) except within
        ``tolerance`` (m) of ``p_to`` (the target's own housing, e.g. a prism or an LED)."""
        a = np.asarray(p_from, dtype=float).reshape(3)
        v = np.asarray(p_to, dtype=float).reshape(3) - a
        length = math.sqrt(v @ v)  # np.linalg.norm(v), without its overhead
        dist, _ = self._cast(a, v / length, exclude_robot)
        return bool(dist >= length - tolerance)

    def export(self, path: str | Path) -> Path:
        """Write the compiled scene as one MJCF file that loads on its own, and return it.

        The scene uses only primitive shapes and built-in textures: no asset files."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.spec.to_xml(), encoding="utf-8")
        return path


def build_world(
    scenario: Scenario,
    control_period: float = 0.02,
    markers: Mapping[str, MarkerAssembly] | None = None,
) -> World:
    """Compose and compile ``scenario`` into a :class:`World` at its start state
    (``markers``: as :func:`build_spec`)."""
    return World(scenario, control_period, markers)


__all__ = ["SPACE_GROUP", "Collision", "DriveResult", "World", "build_spec", "build_world"]


def _ramp(current: float, target: float, step: float) -> float:
    if target > current:
        return min(target, current + step)
    return max(target, current - step)
