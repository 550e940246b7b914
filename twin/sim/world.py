"""The :class:`World` that runs a scenario's compiled MuJoCo model.

A world holds the model and its state and steps them in control periods. Two parts act on
it: :attr:`World.driving` (:mod:`twin.sim.driving`: velocity commands, controllers, the
wheels' hold at rest, odometry, collisions) and :attr:`World.sensing`
(:mod:`twin.sim.sensing`: lines of sight, LEDs, lights). The world itself answers where
things truly are: robots, sites, the instrument, the markers, the cameras.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from twin.instruments.marker import MarkerAssembly
from twin.scenario.schema import Scenario
from twin.sim.camera import tsai_from_model
from twin.sim.controller import DriveTolerance
from twin.sim.driving import Collision, Driving
from twin.sim.people import move_people
from twin.sim.robots import N_CUBES, N_LEDS, RobotHandle
from twin.sim.scene import build_spec
from twin.sim.sensing import Sensing

FELL_OVER_TILT = np.radians(30.0)
"""A robot whose body leans further than this from the vertical has fallen over, rad."""


@dataclass(frozen=True)
class DriveOutcome:
    """How a :meth:`World.drive_to` ended, in the simulator's truth.

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
        driving: the robots' motion (:class:`twin.sim.driving.Driving`).
        sensing: lines of sight, LEDs and lights (:class:`twin.sim.sensing.Sensing`).
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
        self.driving = Driving(self.model, self.data, self.robots, self.control_period)
        self.sensing = Sensing(
            self.model, self.data, self.robots, [c.name for c in scenario.robots.children]
        )
        self.reset()

    # -- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the start poses, time 0, LEDs off, odometry re-seeded from the scenario."""
        mujoco.mj_resetData(self.model, self.data)
        mujoco.mj_forward(self.model, self.data)
        self.driving.reset(self.scenario.seed, self.scenario.noise.odometry.spec())
        self.sensing.reset()
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
        self.driving.stop(robot)
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
        self.driving.put_down(robot)

    def shift(self, robot: str, dxy: ArrayLike) -> None:
        """Move a robot by (2,) ``dxy`` m on the floor at once, without telling its odometry
        (a creep it does not notice); its heading and its rest are kept."""
        h = self.robots[robot]
        self.data.qpos[h.qpos : h.qpos + 2] += np.asarray(dxy, dtype=float).reshape(2)
        mujoco.mj_forward(self.model, self.data)

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
            self.driving.control()
            self.driving.apply_commands()
            if self.scenario.people:
                move_people(
                    self.model, self.data, self.scenario.people, self.scenario.space.floor_z
                )
            mujoco.mj_step(self.model, self.data, nstep=self.substeps)
            self.driving.update_odometry()
            new += self.driving.detect_collisions()
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

    def drive_to(
        self,
        robot: str,
        goal_xy: ArrayLike,
        goal_yaw: float | None = None,
        timeout: float | None = None,
        pose_source: str = "truth",
        tolerance: DriveTolerance | None = None,
    ) -> DriveOutcome:
        """Drive ``robot`` to a goal and step the world until it stops, collides, falls
        over or times out.

        The other robots keep their current commands. On a collision the robot is stopped.

        Args:
            goal_xy, goal_yaw, pose_source, tolerance: as :meth:`Driving.drive`.
            timeout: simulated seconds allowed (default: three times the straight-line
                travel time at top speed, plus 10 s).
        """
        g = np.asarray(goal_xy, dtype=float).reshape(2)
        h = self.robots[robot]
        if timeout is None:
            dist = float(np.linalg.norm(g - h.pose(self.data)[:2]))
            timeout = 3.0 * dist / h.platform.max_speed + 10.0
        ctl = self.driving.drive(robot, g, goal_yaw, pose_source, tolerance)
        t0 = self.time
        mine: list[Collision] = []
        status = "timeout"
        while self.time - t0 < timeout:
            mine += [c for c in self.step() if c.robot == robot]
            if mine:
                self.driving.stop(robot)
                status = "collision"
                break
            if h.tilt(self.data) > FELL_OVER_TILT:
                self.driving.stop(robot)
                status = "fell_over"
                break
            if ctl.done:
                status = "reached"
                break
        self.driving.stop(robot)
        pose = h.pose(self.data)
        return DriveOutcome(
            robot=robot,
            status=status,
            pose=pose,
            position_error=float(np.linalg.norm(pose[:2] - g)),
            duration=self.time - t0,
            collisions=tuple(mine),
        )

    # -- where things truly are ----------------------------------------------------------------
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
    (``markers``: as :func:`twin.sim.scene.build_spec`)."""
    return World(scenario, control_period, markers)
