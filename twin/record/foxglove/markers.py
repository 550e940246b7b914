"""The children's marker assemblies as ``foxglove.SceneUpdate`` entities locked to their
frames: the three prisms (corner cubes), the LEDs and the mast, drawn on each child where
its truth puts it (``ROBOT/truth``) and where its localisation puts it
(``ROBOT/estimate``, paler), so that they move with the robots on Foxglove's timeline.

The geometry is the assembly's body frame (:class:`twin.instruments.marker.
MarkerAssembly`: origin on the floor below the robot's centre, x forward, z up), which is
the origin of both robot frames (:mod:`twin.record.foxglove.frames`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from foxglove.messages import (
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    SceneEntity,
    SpherePrimitive,
)

from twin.record.foxglove.convert import color, point3, pose, timestamp, vector3
from twin.record.foxglove.frames import robot_frame

PRISM_SIZE_M = 0.06
"""Diameter of a prism's sphere, m."""
LED_SIZE_M = 0.04
"""Diameter of an LED's sphere, m."""
PRISM = (0.3, 0.9, 1.0)
LED = (1.0, 0.85, 0.1)
MAST = (0.75, 0.75, 0.75)
ALPHA = {"truth": 1.0, "estimate": 0.35}
"""Opacity of the assembly in each robot frame."""


def marker_id(robot: str, which: str) -> str:
    """The entity id of ``robot``'s assembly in its frame ``which``."""
    return f"{robot}/{which}"


def marker_entity(t: float, robot: str, which: str, marker: Any) -> SceneEntity:
    """``robot``'s assembly (a :class:`MarkerAssembly`) in the frame ``ROBOT/which``
    (``truth`` or ``estimate``) at ``t`` s, locked to that frame.

    Metadata: ``prisms`` and ``leds``, how many of each.
    """
    a = ALPHA[which]
    cubes = np.asarray(marker.cubes_body, dtype=float).reshape(-1, 3)
    leds = np.asarray(marker.leds_body, dtype=float).reshape(-1, 3)
    top = float(cubes[:, 2].mean())
    prism = vector3((PRISM_SIZE_M,) * 3)
    led = vector3((LED_SIZE_M,) * 3)
    spheres = [SpherePrimitive(pose=pose(p), size=prism, color=color(*PRISM, a)) for p in cubes]
    spheres += [SpherePrimitive(pose=pose(p), size=led, color=color(*LED, a)) for p in leds]
    mast = LinePrimitive(
        type=LinePrimitiveLineType.LineList,
        pose=pose((0.0, 0.0, 0.0)),
        thickness=0.02,
        scale_invariant=False,
        points=[point3((0.0, 0.0, 0.0)), point3((0.0, 0.0, top))],
        color=color(*MAST, a),
    )
    meta = [KeyValuePair(key="prisms", value=str(len(cubes)))]
    meta.append(KeyValuePair(key="leds", value=str(len(leds))))
    return SceneEntity(
        timestamp=timestamp(t),
        frame_id=robot_frame(robot, which),
        id=marker_id(robot, which),
        frame_locked=True,
        spheres=spheres,
        lines=[mast],
        metadata=meta,
    )
