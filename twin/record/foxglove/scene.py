"""``foxglove.SceneUpdate`` entities, all in W: the site, the route and stations, the
cameras' view frustums, the LED points, the parent's covariance and the lines of sight.

Colours: the site grey, obstacles brown, the route blue; a camera as built green, as
calibrated blue; LED points grey until their visit is calibrated, then from green (0 px)
to red (:data:`RESIDUAL_FULL_PX` and more) by their residual in that calibration; lines of
sight white, red where the shot failed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from foxglove.messages import (
    Color,
    CubePrimitive,
    Duration,
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Vector3,
)
from numpy.typing import ArrayLike, NDArray

from twin.record.foxglove.convert import color, point3, pose, ramp, timestamp, vector3
from twin.record.foxglove.frames import WORLD

RESIDUAL_FULL_PX = 1.0
"""The residual, px, drawn fully red."""
LED_SIZE_M = 0.04
"""Diameter of an LED point's sphere, m."""
ELLIPSOID_SIGMAS = 3.0
"""The parent's covariance is drawn as the ellipsoid of this many standard deviations..."""
ELLIPSOID_MAGNIFICATION = 100.0
"""... magnified this many times (millimetres would not show in a hall)."""
FRUSTUM_DEPTH_M = (0.5, 15.0)
"""A frustum reaches the floor, but no nearer or farther than these, m."""
SIGHT_LIFETIME_S = 10.0
"""How long a successful shot's line of sight stays in the scene, s (a failed one stays)."""

BUILT = color(0.1, 0.8, 0.2)
CALIBRATED = color(0.2, 0.4, 1.0)
GREY = color(0.6, 0.6, 0.6)
RED = color(1.0, 0.1, 0.1)


def update(entities: Sequence[SceneEntity]) -> SceneUpdate:
    """Entities as one message."""
    return SceneUpdate(entities=list(entities))


def entity(
    t: float, id_: str, metadata: Mapping[str, str] | None = None, **prims: Any
) -> SceneEntity:
    """An entity in W at ``t`` s made of ``prims`` (``cubes=[...]``, ``lines=[...]``...)."""
    meta = [KeyValuePair(key=k, value=str(v)) for k, v in (metadata or {}).items()]
    return SceneEntity(timestamp=timestamp(t), frame_id=WORLD, id=id_, metadata=meta, **prims)


def _box(center: ArrayLike, size: ArrayLike, yaw: float, c: Color) -> CubePrimitive:
    rot = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    return CubePrimitive(pose=pose(center, rot), size=_vec(size), color=c)


def _vec(v: ArrayLike) -> Vector3:
    return vector3(v)


def site_entities(scenario: Any) -> list[SceneEntity]:
    """The site as the scenario's world has it: ``floor`` (a slab under the floor), ``walls``
    (the four around the room, ``space.wall_thickness`` thick), ``obstacles`` (each box or
    flight of stairs as the box it fills), ``route`` (the parent's route on the floor) and
    ``stations`` (each visit's station, named)."""
    space = scenario.space
    (ox, oy), (lx, ly, lz), fz = space.origin, space.size, space.floor_z
    w = space.wall_thickness
    cx, cy = ox + lx / 2, oy + ly / 2
    floor = [_box((cx, cy, fz - 0.005), (lx, ly, 0.01), 0.0, color(0.8, 0.8, 0.8, 0.6))]
    wall_c = color(0.7, 0.7, 0.75, 0.35)
    walls = [
        _box((cx, oy - w / 2, fz + lz / 2), (lx + 2 * w, w, lz), 0.0, wall_c),
        _box((cx, oy + ly + w / 2, fz + lz / 2), (lx + 2 * w, w, lz), 0.0, wall_c),
        _box((ox - w / 2, cy, fz + lz / 2), (w, ly, lz), 0.0, wall_c),
        _box((ox + lx + w / 2, cy, fz + lz / 2), (w, ly, lz), 0.0, wall_c),
    ]
    obstacle_c = color(0.55, 0.4, 0.25, 0.8)
    obstacles = [
        _box((*o.center, fz + o.size[2] / 2), o.size, o.yaw, obstacle_c) for o in space.obstacles
    ]
    route = LinePrimitive(
        type=LinePrimitiveLineType.LineStrip,
        pose=pose((0.0, 0.0, 0.0)),
        thickness=0.05,
        points=[point3((x, y, fz + 0.01)) for x, y in scenario.route.waypoints],
        color=color(0.2, 0.5, 1.0),
    )
    stations, labels, counts = [], [], {}
    for v in scenario.calibration.visits:
        counts[v.camera] = counts.get(v.camera, 0) + 1
        at = (float(v.station[0]), float(v.station[1]), fz + 0.05)
        stations.append(SpherePrimitive(pose=pose(at), size=_vec((0.2, 0.2, 0.1)), color=BUILT))
        labels.append(
            TextPrimitive(
                pose=pose((at[0], at[1], at[2] + 0.3)),
                billboard=True,
                font_size=14.0,
                scale_invariant=True,
                color=color(1, 1, 1),
                text=f"{v.camera} visit {counts[v.camera]}",
            )
        )
    return [
        entity(0.0, "floor", cubes=floor),
        entity(0.0, "walls", cubes=walls),
        entity(0.0, "obstacles", cubes=obstacles),
        entity(0.0, "route", lines=[route]),
        entity(0.0, "stations", spheres=stations, texts=labels),
    ]


def frustum_entity(
    t: float, id_: str, camera: Any, floor_z: float, c: Color, metadata: Mapping[str, str]
) -> SceneEntity:
    """A camera's view frustum (a calib camera): lines from its optical centre through the
    image's corners, to the floor ``floor_z`` (m) within :data:`FRUSTUM_DEPTH_M`, and the
    far rectangle; with the camera's name as text."""
    pts = frustum_points(camera, floor_z)
    c0 = pts[0]
    line = LinePrimitive(
        type=LinePrimitiveLineType.LineList,
        pose=pose((0.0, 0.0, 0.0)),
        thickness=2.0,
        scale_invariant=True,
        points=[point3(p) for p in pts],
        color=c,
    )
    label = TextPrimitive(
        pose=pose(c0 + np.array([0.0, 0.0, 0.3])),
        billboard=True,
        font_size=14.0,
        scale_invariant=True,
        color=c,
        text=id_.split("/", 1)[-1],
    )
    return entity(t, id_, metadata, lines=[line], texts=[label])


def frustum_points(camera: Any, floor_z: float) -> NDArray[np.float64]:
    """A camera's view frustum as (16, 3) m, pairs of points (a line list): its optical
    centre to each far corner, and the far rectangle, which reaches the floor ``floor_z``
    (m) within :data:`FRUSTUM_DEPTH_M`."""
    w, h = camera.image_size
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    origins, directions = camera.unproject(corners)
    c0 = origins[0]
    lo, hi = FRUSTUM_DEPTH_M
    down = -directions[:, 2]
    depth = np.where(down > 1e-6, (c0[2] - floor_z) / np.maximum(down, 1e-6), hi)
    depth = float(np.clip(np.min(depth), lo, hi))
    far = c0 + depth * directions
    pts: list[NDArray] = []
    for k in range(4):
        pts += [c0, far[k], far[k], far[(k + 1) % 4]]
    return np.array(pts)


def points_entity(
    t: float, id_: str, leds_world: ArrayLike, residuals_px: ArrayLike | None
) -> SceneEntity:
    """One stop's LED points (N, 3) m as spheres, coloured by their residuals (N,) px
    (grey when None)."""
    leds = np.asarray(leds_world, dtype=float).reshape(-1, 3)
    res = np.full(len(leds), np.nan) if residuals_px is None else np.asarray(residuals_px)
    size = _vec((LED_SIZE_M, LED_SIZE_M, LED_SIZE_M))
    spheres = [
        SpherePrimitive(pose=pose(p), size=size, color=ramp(float(r), RESIDUAL_FULL_PX))
        for p, r in zip(leds, res, strict=True)
    ]
    meta = {} if residuals_px is None else {"residuals_px": " ".join(f"{r:.3f}" for r in res)}
    return entity(t, id_, meta, spheres=spheres)


def ellipsoid_entity(
    t: float, id_: str, center: ArrayLike, covariance: ArrayLike
) -> SceneEntity | None:
    """The (3, 3) position covariance (m^2) at ``center`` (3,) m as an ellipsoid of
    :data:`ELLIPSOID_SIGMAS` standard deviations magnified :data:`ELLIPSOID_MAGNIFICATION`
    times; None for a covariance that is not positive (the first station's)."""
    cov = np.asarray(covariance, dtype=float)
    if not np.all(np.isfinite(cov)):
        return None
    values, vectors = np.linalg.eigh((cov + cov.T) / 2)
    if values[-1] <= 0:
        return None
    if np.linalg.det(vectors) < 0:
        vectors[:, 0] = -vectors[:, 0]
    sigmas = np.sqrt(np.maximum(values, 0.0))
    size = 2.0 * ELLIPSOID_SIGMAS * ELLIPSOID_MAGNIFICATION * sigmas
    sphere = SpherePrimitive(
        pose=pose(center, vectors), size=_vec(size), color=color(1, 0.6, 0, 0.5)
    )
    meta = {
        "sigmas_mm": " ".join(f"{1e3 * s:.3f}" for s in sigmas),
        "drawn": f"{ELLIPSOID_SIGMAS:g} sigma x {ELLIPSOID_MAGNIFICATION:g}",
    }
    return entity(t, id_, meta, spheres=[sphere])


def sight_entity(t: float, id_: str, start: ArrayLike, end: ArrayLike, failed: bool) -> SceneEntity:
    """A line of sight from the instrument ``start`` to ``end`` (3,) m in W: white, red
    and lasting where the shot ``failed``."""
    line = LinePrimitive(
        type=LinePrimitiveLineType.LineList,
        pose=pose((0.0, 0.0, 0.0)),
        thickness=2.0 if failed else 1.0,
        scale_invariant=True,
        points=[point3(start), point3(end)],
        color=RED if failed else color(1, 1, 1, 0.8),
    )
    extra = {}
    if not failed:
        ns = round(SIGHT_LIFETIME_S * 1e9)
        extra["lifetime"] = Duration(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)
    return entity(t, id_, {"failed": str(failed).lower()}, lines=[line], **extra)
