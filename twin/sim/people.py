"""People walking through the space: moving distractors for the cameras.

Each person is a mocap body (moved by the simulator, not by physics) made of legs, a
torso in the shirt's colour, arms and a head. The geoms are in the space's geom group, so
they are drawn and block lines of sight (a person between the total station and a prism
hides it), but they have no contacts: robots pass through people.

A person walks along the path of waypoints to its end and back, at constant speed, facing
the direction of travel; :func:`person_pose` gives the pose at any time.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from numpy.typing import NDArray

from twin.scenario.schema import Person
from twin.sim.hall import SPACE_GROUP

# Body proportions as fractions of the height, and widths, m.
LEG_TOP = 0.47
SHOULDER = 0.82
HEAD_RADIUS = 0.11
TORSO_HALF_WIDTH = 0.20
TORSO_HALF_DEPTH = 0.12
LIMB_RADIUS = 0.06
TROUSERS_RGBA = (0.15, 0.17, 0.25, 1.0)
SKIN_RGBA = (0.80, 0.62, 0.50, 1.0)


def add_person(spec: mujoco.MjSpec, person: Person, floor_z: float) -> None:
    """Add ``person`` to ``spec`` as a mocap body ``NAME`` standing on the floor."""
    body = spec.worldbody.add_body(name=person.name, mocap=True, pos=[0.0, 0.0, floor_z])
    h = person.height
    common = {"contype": 0, "conaffinity": 0, "group": SPACE_GROUP, "density": 0.0}
    cap = mujoco.mjtGeom.mjGEOM_CAPSULE
    for side, y in (("left", 0.1), ("right", -0.1)):
        body.add_geom(
            name=f"{person.name}/{side}_leg",
            type=cap,
            fromto=[0.0, y, LIMB_RADIUS, 0.0, y, LEG_TOP * h],
            size=[LIMB_RADIUS + 0.01, 0, 0],
            rgba=TROUSERS_RGBA,
            **common,
        )
        body.add_geom(
            name=f"{person.name}/{side}_arm",
            type=cap,
            fromto=[0.0, 2.6 * y, SHOULDER * h, 0.0, 2.7 * y, (LEG_TOP + 0.02) * h],
            size=[0.8 * LIMB_RADIUS, 0, 0],
            rgba=(*person.shirt_rgb, 1.0),
            **common,
        )
    body.add_geom(
        name=f"{person.name}/torso",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[0.0, 0.0, 0.5 * (LEG_TOP + SHOULDER) * h],
        size=[TORSO_HALF_DEPTH, TORSO_HALF_WIDTH, 0.5 * (SHOULDER - LEG_TOP) * h],
        rgba=(*person.shirt_rgb, 1.0),
        **common,
    )
    body.add_geom(
        name=f"{person.name}/head",
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        pos=[0.0, 0.0, h - HEAD_RADIUS],
        size=[HEAD_RADIUS, 0, 0],
        rgba=SKIN_RGBA,
        **common,
    )


def person_pose(person: Person, time: float) -> tuple[NDArray[np.float64], float]:
    """Where ``person`` stands at ``time`` (s): (2,) floor position (m) and heading (rad,
    in (-pi, pi]).

    The person starts ``start_offset`` metres along the path and walks to its end and back.
    """
    p = np.asarray(person.waypoints, dtype=float)
    # Repeated waypoints add nothing to the path.
    p = p[np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 0.0]]
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    total = float(seg.sum())
    s = (person.start_offset + person.speed * time) % (2.0 * total)
    forward = s <= total
    d = s if forward else 2.0 * total - s
    ends = np.cumsum(seg)
    i = min(int(np.searchsorted(ends, d)), len(seg) - 1)
    direction = (p[i + 1] - p[i]) / seg[i]
    xy = p[i] + (d - (ends[i] - seg[i])) * direction
    sign = 1.0 if forward else -1.0
    return xy, math.atan2(sign * direction[1], sign * direction[0])


def move_people(
    model: mujoco.MjModel, data: mujoco.MjData, people: tuple[Person, ...], floor_z: float
) -> None:
    """Set every person's mocap pose for the data's current time (no kinematics update)."""
    for person in people:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, person.name)
        mocap = int(model.body_mocapid[body])
        xy, heading = person_pose(person, float(data.time))
        data.mocap_pos[mocap] = [xy[0], xy[1], floor_z]
        data.mocap_quat[mocap] = [math.cos(0.5 * heading), 0.0, 0.0, math.sin(0.5 * heading)]
