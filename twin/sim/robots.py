"""The robot models: loading a device's MJCF and attaching it to a scene under a prefix.

After :func:`attach_robot`, every name of the device is prefixed with ``ROBOT/``, e.g.
``parent/base`` (body), ``parent/instrument`` (site), ``child1/cube0`` (site),
``child1/led2`` (geom, site and material), ``child1/left_wheel`` (joint and actuator).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from twin.instruments.marker import MarkerAssembly
from twin.scenario.robots import Platform
from twin.scenario.schema import RobotConfig

N_CUBES = 3
N_LEDS = 4

# How far inside an LED (from its centre towards the mast) its stub ends, m.
LED_STUB_INSET = 0.005


def load_device(platform: Platform) -> mujoco.MjSpec:
    """A fresh spec of the device's MJCF file (``models/<model>/<model>.xml``)."""
    return mujoco.MjSpec.from_file(str(platform.xml_path))


def set_marker_geometry(spec: mujoco.MjSpec, marker: MarkerAssembly) -> None:
    """Move a pioneer3dx spec's cube and LED sites and geoms to ``marker``'s geometry.

    The mast is stretched to the highest point, and the cube arms and LED stubs follow
    the cubes and LEDs.
    """
    cubes = np.asarray(marker.cubes_body, dtype=float).reshape(N_CUBES, 3)
    leds = np.asarray(marker.leds_body, dtype=float).reshape(N_LEDS, 3)
    for k, p in enumerate(cubes):
        spec.site(f"cube{k}").pos = p.tolist()
        spec.geom(f"prism{k}").pos = p.tolist()
        arm = spec.geom(f"arm{k}")
        arm.fromto = [0.0, 0.0, p[2] - 0.02, p[0], p[1], p[2] - 0.02]
    for k, p in enumerate(leds):
        spec.site(f"led{k}").pos = p.tolist()
        spec.geom(f"led{k}").pos = p.tolist()
        # The stub runs from the mast's axis to just inside the LED; an LED on the axis
        # keeps a short stub hidden inside it.
        reach = float(np.hypot(p[0], p[1]))
        if reach > LED_STUB_INSET:
            end = p[:2] * (1.0 - LED_STUB_INSET / reach)
            spec.geom(f"stub{k}").fromto = [0.0, 0.0, p[2], end[0], end[1], p[2]]
        else:
            spec.geom(f"stub{k}").fromto = [p[0], p[1], p[2] - 0.01, p[0], p[1], p[2]]
    top = float(max(cubes[:, 2].max(), leds[:, 2].max()))
    spec.geom("mast").fromto = [0.0, 0.0, 0.22, 0.0, 0.0, top]


def attach_robot(
    spec: mujoco.MjSpec,
    robot: RobotConfig,
    floor_z: float,
    marker: MarkerAssembly | None = None,
) -> None:
    """Attach ``robot`` to ``spec`` at its start pose, names prefixed with ``name/``.

    Args:
        spec: the scene.
        robot: which device and where it starts.
        floor_z: the floor's height in the world frame, m (the body origin sits on it).
        marker: marker geometry for a pioneer3dx (default: as in its MJCF file).
    """
    device = load_device(robot.platform)
    if marker is not None and robot.model == "pioneer3dx":
        set_marker_geometry(device, marker)
    x, y, z, w = Rotation.from_euler("z", robot.start_yaw).as_quat()
    frame = spec.worldbody.add_frame(
        pos=[robot.start_xy[0], robot.start_xy[1], floor_z], quat=[w, x, y, z]
    )
    spec.attach(device, prefix=f"{robot.name}/", frame=frame)


@dataclass(frozen=True)
class RobotHandle:
    """Indices of one robot in a compiled model.

    Attributes:
        name: the robot's name (its prefix without the slash).
        platform: dimensions and limits.
        body: id of its root body ``NAME/base``.
        qpos: address of its free joint in ``qpos`` (x, y, z, qw, qx, qy, qz).
        qvel: address of its free joint in ``qvel``.
        left_qpos, right_qpos: ``qpos`` addresses of the left and right wheel joints.
        left_act, right_act: actuator ids of the left and right wheels.
        geoms: ids of every geom of the robot.
        chassis: id of its chassis collision geom.
    """

    name: str
    platform: Platform
    body: int
    qpos: int
    qvel: int
    left_qpos: tuple[int, ...]
    right_qpos: tuple[int, ...]
    left_act: tuple[int, ...]
    right_act: tuple[int, ...]
    geoms: frozenset[int]
    chassis: int

    @classmethod
    def from_model(cls, model: mujoco.MjModel, name: str, platform: Platform) -> RobotHandle:
        """Look the robot's elements up by name."""

        def oid(kind: mujoco.mjtObj, local: str) -> int:
            i = mujoco.mj_name2id(model, kind, f"{name}/{local}")
            if i < 0:
                raise KeyError(f"model has no {kind.name} named {name}/{local}")
            return i

        body = oid(mujoco.mjtObj.mjOBJ_BODY, "base")
        root = oid(mujoco.mjtObj.mjOBJ_JOINT, "root")
        jnt = mujoco.mjtObj.mjOBJ_JOINT
        act = mujoco.mjtObj.mjOBJ_ACTUATOR
        bodies = {b for b in range(model.nbody) if _root_of(model, b) == body}
        geoms = frozenset(g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies)
        return cls(
            name=name,
            platform=platform,
            body=body,
            qpos=int(model.jnt_qposadr[root]),
            qvel=int(model.jnt_dofadr[root]),
            left_qpos=tuple(int(model.jnt_qposadr[oid(jnt, n)]) for n in platform.wheels_left),
            right_qpos=tuple(int(model.jnt_qposadr[oid(jnt, n)]) for n in platform.wheels_right),
            left_act=tuple(oid(act, n) for n in platform.wheels_left),
            right_act=tuple(oid(act, n) for n in platform.wheels_right),
            geoms=geoms,
            chassis=oid(mujoco.mjtObj.mjOBJ_GEOM, "chassis"),
        )

    def pose(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """(3,) planar pose (x, y, yaw) of the body origin, m and rad."""
        q = data.qpos[self.qpos : self.qpos + 7]
        w, x, y, z = q[3:7]
        yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        return np.array([q[0], q[1], yaw])

    def tilt(self, data: mujoco.MjData) -> float:
        """Angle between the body's z axis and the world's vertical, rad (0 when upright)."""
        x, y = data.qpos[self.qpos + 4 : self.qpos + 6]
        cos_tilt = 1.0 - 2.0 * (x * x + y * y)
        return float(np.arccos(np.clip(cos_tilt, -1.0, 1.0)))

    def wheel_angles(self, data: mujoco.MjData) -> tuple[float, float]:
        """Mean (left, right) wheel angles, rad."""
        q = data.qpos
        left = sum(float(q[i]) for i in self.left_qpos) / len(self.left_qpos)
        right = sum(float(q[i]) for i in self.right_qpos) / len(self.right_qpos)
        return left, right


def _root_of(model: mujoco.MjModel, body: int) -> int:
    while model.body_parentid[body] != 0:
        body = int(model.body_parentid[body])
    return body
