"""The space, built in code from the scenario: floor, walls, obstacles, floor patches, lights.

Everything is made of planes and boxes (cheap to collide and to ray-cast). Stairs are a run
of boxes. All geoms of the space are in geom group 0 (rendered, and seen by line-of-sight
rays) and named:

- ``floor``; ``wall_south``, ``wall_north``, ``wall_west``, ``wall_east``;
- an obstacle ``NAME`` of kind ``box``: geom ``NAME``; of kind ``stairs``: ``NAME/step00``...;
- a floor patch ``NAME``: geom ``NAME``.

Contact bits: floor and patches have contype 1 (wheels touch them), walls and obstacles
contype 2 (robot chassis collide with them). See the robot models' READMEs.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from twin.scenario.schema import FloorPatch, Obstacle, Space

FLOOR_BIT = 1
OBSTACLE_BIT = 2
ROBOT_BIT = 4
SPACE_GROUP = 0
PATCH_THICKNESS = 0.05


def _quat_wxyz(rot: Rotation) -> list[float]:
    x, y, z, w = rot.as_quat()
    return [float(w), float(x), float(y), float(z)]


def add_materials(spec: mujoco.MjSpec) -> None:
    """Textures and materials used by the space."""
    spec.add_texture(
        name="floor_tiles",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.55, 0.55, 0.52],
        rgb2=[0.48, 0.48, 0.45],
        width=256,
        height=256,
    )
    floor = spec.add_material(name="floor", texrepeat=[1.0, 1.0], texuniform=True)
    floor.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor_tiles"
    spec.add_material(name="wall", rgba=[0.80, 0.79, 0.75, 1.0])
    spec.add_material(name="obstacle", rgba=[0.45, 0.45, 0.47, 1.0])
    spec.add_material(name="patch", rgba=[0.58, 0.56, 0.50, 1.0])


def build_space(spec: mujoco.MjSpec, space: Space) -> None:
    """Add the floor, walls, obstacles, floor patches and lights of ``space`` to ``spec``."""
    add_materials(spec)
    wb = spec.worldbody
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    lx, ly, lz = space.size
    t = space.wall_thickness
    static = {"group": SPACE_GROUP, "conaffinity": 0}
    wb.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        pos=[cx, cy, space.floor_z],
        size=[0.5 * lx + t, 0.5 * ly + t, 0.05],
        material="floor",
        contype=FLOOR_BIT,
        **static,
    )
    walls = {
        "wall_south": ([cx, y0 - 0.5 * t], [0.5 * lx + t, 0.5 * t]),
        "wall_north": ([cx, y1 + 0.5 * t], [0.5 * lx + t, 0.5 * t]),
        "wall_west": ([x0 - 0.5 * t, cy], [0.5 * t, 0.5 * ly]),
        "wall_east": ([x1 + 0.5 * t, cy], [0.5 * t, 0.5 * ly]),
    }
    for name, (xy, half) in walls.items():
        wb.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=[xy[0], xy[1], space.floor_z + 0.5 * lz],
            size=[half[0], half[1], 0.5 * lz],
            material="wall",
            contype=OBSTACLE_BIT,
            **static,
        )
    for ob in space.obstacles:
        add_obstacle(wb, ob, space.floor_z)
    for patch in space.floor_patches:
        add_floor_patch(wb, patch, space.floor_z)
    add_lights(spec, space)


def add_obstacle(body: mujoco.MjsBody, ob: Obstacle, floor_z: float) -> None:
    """A box, or a staircase rising along the obstacle's local x, standing on the floor."""
    quat = _quat_wxyz(Rotation.from_euler("z", ob.yaw))
    rot = Rotation.from_euler("z", ob.yaw)
    sx, sy, sz = ob.size
    common = {
        "type": mujoco.mjtGeom.mjGEOM_BOX,
        "material": "obstacle",
        "contype": OBSTACLE_BIT,
        "conaffinity": 0,
        "group": SPACE_GROUP,
        "quat": quat,
    }
    if ob.kind == "box":
        body.add_geom(
            name=ob.name,
            pos=[ob.center[0], ob.center[1], floor_z + 0.5 * sz],
            size=[0.5 * sx, 0.5 * sy, 0.5 * sz],
            **common,
        )
        return
    # Stairs: step k spans local x from its front edge to the back, height (k + 1) / n.
    n = ob.steps
    run = sx / n
    for k in range(n):
        x_front = -0.5 * sx + k * run
        length = sx - k * run
        height = (k + 1) * sz / n
        local = np.array([x_front + 0.5 * length, 0.0, 0.0])
        xy = np.asarray(ob.center) + rot.apply(local)[:2]
        body.add_geom(
            name=f"{ob.name}/step{k:02d}",
            pos=[float(xy[0]), float(xy[1]), floor_z + 0.5 * height],
            size=[0.5 * length, 0.5 * sy, 0.5 * height],
            **common,
        )


def add_floor_patch(body: mujoco.MjsBody, patch: FloorPatch, floor_z: float) -> None:
    """A thin slab tilted about world x then y, its lowest edge flush with the floor."""
    tx, ty = patch.tilt
    rot = Rotation.from_euler("xy", [tx, ty])
    hx, hy = 0.5 * patch.size[0], 0.5 * patch.size[1]
    # Height of the top face's centre so that its lowest corner is at the floor.
    top_corners = rot.apply(np.array([[sx * hx, sy * hy, 0.0] for sx in (-1, 1) for sy in (-1, 1)]))
    lift = -float(top_corners[:, 2].min())
    normal = rot.apply([0.0, 0.0, 1.0])
    centre = np.array([patch.center[0], patch.center[1], floor_z + lift])
    centre -= 0.5 * PATCH_THICKNESS * normal
    body.add_geom(
        name=patch.name,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=centre.tolist(),
        quat=_quat_wxyz(rot),
        size=[hx, hy, 0.5 * PATCH_THICKNESS],
        material="patch",
        contype=FLOOR_BIT,
        conaffinity=0,
        group=SPACE_GROUP,
    )


def add_lights(spec: mujoco.MjSpec, space: Space) -> None:
    """Overhead lights on a grid under the ceiling (at most 8) and the ambient level.

    Shadows are off unless the scenario's ``space.lighting.shadows`` is true: they cost
    three to five times the render time.
    """
    lit = space.lighting
    spec.visual.headlight.ambient = [lit.ambient] * 3
    spec.visual.headlight.diffuse = [0.2] * 3
    spec.visual.headlight.specular = [0.0] * 3
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    nx = max(1, min(8, math.ceil((x1 - x0) / lit.spacing)))
    ny = max(1, min(8 // nx, math.ceil((y1 - y0) / lit.spacing)))
    z = space.floor_z + space.size[2] - 0.3
    for i in range(nx):
        for j in range(ny):
            x = x0 + (i + 0.5) * (x1 - x0) / nx
            y = y0 + (j + 0.5) * (y1 - y0) / ny
            light = spec.worldbody.add_light(name=f"light_{i}_{j}", pos=[x, y, z])
            light.type = mujoco.mjtLightType.mjLIGHT_POINT
            light.diffuse = [lit.diffuse] * 3
            light.specular = [0.05] * 3
            light.castshadow = lit.shadows
