"""Where the robots go: CPS legs along the route, the children's formation, and the child's
stops over a camera's view.

Everything here is planned on the scenario's map (walls, obstacles, the cameras' nominal
poses) and the campaign's current estimates; nothing is measured here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from calib.rotation import wrap_angle
from twin.campaign.geometry import (
    body_points,
    child_profile,
    free,
    parent_profile,
    passes_near,
    sight_clear,
    unhidden_yaw,
)
from twin.campaign.route import RoutePath
from twin.scenario.geometry import floor_view
from twin.scenario.schema import FormationSettings, Scenario

IMAGE_MARGIN = 12.0
"""The planned LED pixels stay this far inside the image, px, so that a child that stops a
few centimetres off still shows all four LEDs."""

MIN_SEPARATION = math.radians(4.0)
"""Least angle between the two children seen from the parent, so that an aim at one is
not nearer the other (a parent that just moved knows its heading to about a degree)."""

FORMATION_CLEARANCE = 0.35
"""Distance kept between a child's centre and walls in the formation, m (its radius, 0.29 m,
and its stopping error: narrow corridors need the children close to the walls)."""

SIGHT_MARGIN = 0.10
"""A formation's lines of sight pass obstacles by at least this much, m: a child stops
centimetres from its goal (further on wheel odometry), and a prism planned to graze a
corner would be hidden."""

RANGE_MARGIN = 0.3
"""Prisms are planned at least this much beyond the instrument's minimum range, m."""


@dataclass(frozen=True)
class Stop:
    """A planned stop of a robot: (x, y) m and heading rad in W."""

    xy: NDArray[np.float64]
    yaw: float


def leg_goals(path: RoutePath, s_from: float, s_to: float, step: float) -> list[float]:
    """Arc lengths of the parent's stations from ``s_from`` to ``s_to`` in equal legs of at
    most ``step`` m (the last is ``s_to``)."""
    n = max(1, math.ceil(abs(s_to - s_from) / step - 1e-9))
    return [s_from + (s_to - s_from) * (k + 1) / n for k in range(n)]


def _instrument(xy: ArrayLike, instrument_z: float) -> NDArray[np.float64]:
    p = np.asarray(xy, dtype=float).reshape(2)
    return np.array([p[0], p[1], instrument_z])


def formation(
    scenario: Scenario,
    path: RoutePath,
    s_next: float,
    parent_now: ArrayLike,
    parent_next: ArrayLike,
    direction: float,
    form: FormationSettings,
    instrument_z: float,
    waiting_xy: ArrayLike | None = None,
) -> list[Stop] | None:
    """Stops of the two children ahead of the parent's next station.

    The children stand ahead (in the direction of travel, ``direction`` = +1 or -1 along the
    path) of ``s_next``, staggered sideways; each must be free, in range and in sight of the
    instrument at both the parent's current and next stations, and the two must be at least
    ``MIN_SEPARATION`` apart seen from both. Smaller, mirrored and zero offsets and shorter
    gaps are tried in turn. Returns the far child's stop first (it moves first), or None.

    ``waiting_xy`` (2,), m: where the other child stands while the far one is measured from
    the current station (it moves second); it must not hide the far child's prisms.
    """
    cubes = np.asarray(scenario.marker.cubes, dtype=float)
    ts = scenario.noise.total_station
    stations = [_instrument(parent_now, instrument_z), _instrument(parent_next, instrument_z)]
    gaps = [form.near_gap, 0.75 * form.near_gap + 0.5, 2.0]
    lat = form.lateral
    # (near, far) sideways offsets: staggered either way, then both to one side.
    sides = [(lat, -lat), (-lat, lat), (0.5 * lat, -0.5 * lat), (-0.5 * lat, 0.5 * lat)]
    sides += [(a * lat, b * lat) for a, b in ((0, -1), (0, 1), (-1, 0), (1, 0), (-1.5, -0.3))]
    sides += [(a * lat, b * lat) for a, b in ((1.5, 0.3), (-0.3, -1.5), (0.3, 1.5))]
    sides += [(0.3, -0.3), (-0.3, 0.3), (0.15, -0.15), (-0.15, 0.15)]  # narrow corridors
    for gap in gaps:
        for spacing in (form.spacing, 0.7 * form.spacing):
            for near_side, far_side in sides:
                places = []
                for ahead, side in ((gap + spacing, far_side), (gap, near_side)):
                    s = s_next + direction * ahead
                    yaw = path.heading(s) + (0.0 if direction > 0 else math.pi)
                    places.append((path.offset(s, side * direction), yaw))
                # Where the children stand decides most; their headings cost more to find.
                if not _places_ok(scenario, [xy for xy, _ in places], stations):
                    continue
                stops = []
                for xy, yaw in places:
                    turned = unhidden_yaw(xy, yaw, cubes, stations, scenario.space.floor_z)
                    if turned is None:
                        break  # every heading hides a prism from a station
                    stops.append(Stop(xy, turned))
                if len(stops) == len(places) and _formation_ok(
                    scenario, stops, stations, cubes, ts.range_min, ts.range_max, waiting_xy
                ):
                    return stops
    return None


def _places_ok(
    scenario: Scenario, places: list[NDArray[np.float64]], stations: list[NDArray[np.float64]]
) -> bool:
    """Whether the children's (2,) places (m) are free, 1 m apart and 1 m from each
    instrument ((3,) positions, m)."""
    xy = np.array(places)
    if not free(scenario, xy, FORMATION_CLEARANCE).all():
        return False
    if np.linalg.norm(xy[0] - xy[1]) < 1.0:
        return False
    return all(np.min(np.linalg.norm(xy - inst[:2], axis=1)) >= 1.0 for inst in stations)


def _formation_ok(
    scenario: Scenario,
    stops: list[Stop],
    stations: list[NDArray[np.float64]],
    cubes: NDArray[np.float64],
    range_min: float,
    range_max: float,
    waiting_xy: ArrayLike | None = None,
) -> bool:
    """Whether the children's stops suit both stations: see :func:`formation`. Their
    headings already keep every prism clear of its own assembly (:func:`unhidden_yaw`)."""
    xy = np.array([s.xy for s in stops])
    if not _places_ok(scenario, list(xy), stations):
        return False
    floor = scenario.space.floor_z
    if waiting_xy is not None:
        far = body_points(stops[0].xy, stops[0].yaw, cubes, floor)[0]
        if passes_near(stations[0], far, waiting_xy, child_profile(floor)).any():
            return False
    for inst in stations:
        bearings = []
        for k, stop in enumerate(stops):
            pts = body_points(stop.xy, stop.yaw, cubes, floor)[0]
            d = np.linalg.norm(pts - inst, axis=1)
            if d.min() < range_min + RANGE_MARGIN or d.max() > range_max:
                return False
            if not sight_clear(scenario, inst, pts, SIGHT_MARGIN).all():
                return False
            other = xy[1 - k]
            if passes_near(inst, pts, other, child_profile(floor)).any():
                return False
            v = stop.xy - inst[:2]
            bearings.append(math.atan2(v[1], v[0]))
        sep = abs(wrap_angle(bearings[0] - bearings[1]))
        if sep < MIN_SEPARATION:
            return False
    return True


@dataclass(frozen=True)
class ViewStop:
    """A planned stop of a child in a camera's view.

    Attributes:
        stop: where the child stands, facing the camera.
        pixels: (N_led, 2) where the camera's nominal model expects its LEDs, px.
    """

    stop: Stop
    pixels: NDArray[np.float64]


def view_stops(
    scenario: Scenario,
    camera: TsaiCamera,
    parent_xy: ArrayLike,
    instrument_z: float,
    anchor_xy: ArrayLike | None,
    grid: int = 40,
) -> list[ViewStop]:
    """Where a child can stand to show all its LEDs to ``camera``, in the order to use them.

    Candidates come from the camera's view of the floor and of planes at the LEDs' heights
    (``grid / 2`` x ``grid / 2`` samples of the image each). A candidate is kept when the
    child, facing the camera, is free of walls and obstacles and clear of the parent and
    the anchor child; all four LEDs project inside the image with ``IMAGE_MARGIN`` and
    nothing on the map, the parent or the anchor hides them from the camera; and the total
    station sees its three prisms in range. The order is farthest-point sampling in (image
    column, image row, distance), starting next to the image centre: any first n stops
    spread over the view and depth.

    Args:
        scenario: the map. camera: the camera's nominal model (world frame).
        parent_xy: the parent's position, m. instrument_z: the instrument's height in W, m.
        anchor_xy: the other child's position (it stays), m, or None.
    """
    floor = scenario.space.floor_z
    leds = np.asarray(scenario.marker.leds, dtype=float)
    cubes = np.asarray(scenario.marker.cubes, dtype=float)
    # Where the image's rays meet planes at the LEDs' heights: a steep camera sees the top
    # LED only far beyond where it sees the floor.
    heights = np.linspace(0.0, float(leds[:, 2].max()), 4)
    ground = np.vstack([floor_view(camera, floor + z, 40.0, grid // 2) for z in heights])
    if len(ground) == 0:
        return []
    xy = ground[:, :2]
    cam = camera.position
    yaw = np.arctan2(cam[1] - xy[:, 1], cam[0] - xy[:, 0])
    # The mast is at the body origin and the LEDs stand in front of it: move the body back
    # so that the mast, not the body origin, is where the image row points.
    ok = free(scenario, xy)
    parent = np.asarray(parent_xy, dtype=float).reshape(2)
    ok &= np.linalg.norm(xy - parent, axis=1) > 1.2
    anchor = None if anchor_xy is None else np.asarray(anchor_xy, float).reshape(2)
    if anchor is not None:
        ok &= np.linalg.norm(xy - anchor, axis=1) > 1.2
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    led_w = body_points(xy[idx], yaw[idx], leds, floor)
    cube_w = body_points(xy[idx], yaw[idx], cubes, floor)
    inst = np.array([parent[0], parent[1], instrument_z])
    # Each test on the candidates that passed the ones before (the cheap ones first).
    sel, pix = _leds_in_image(camera, led_w)
    sel = sel[_leds_seen(scenario, cam, led_w[sel], parent, anchor)]
    sel = sel[_prisms_seen(scenario, inst, cube_w[sel], anchor)]
    if sel.size == 0:
        return []
    keep = idx[sel]
    pix = pix[sel]
    w, h = camera.image_size
    depth = np.linalg.norm(xy[keep] - cam[:2], axis=1)
    feats = np.column_stack(
        [
            pix[:, :, 0].mean(axis=1) / w,
            pix[:, :, 1].mean(axis=1) / h,
            (depth - depth.min()) / max(np.ptp(depth), 1e-9),
        ]
    )
    order = _farthest_first(feats, start=np.array([0.5, 0.5, 0.5]))
    return [ViewStop(Stop(xy[keep[k]].copy(), float(yaw[keep[k]])), pix[k]) for k in order]


def _leds_in_image(
    camera: TsaiCamera, led_w: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Which of N candidates' (N, K, 3) LEDs (W, m) all lie more than 0.1 m in front of
    the camera and project inside its image with ``IMAGE_MARGIN``.

    Returns:
        (M,) indices of those candidates, and (N, K, 2) every candidate's pixels (NaN
        where an LED cannot be projected), px.
    """
    n, k = led_w.shape[:2]
    flat = led_w.reshape(-1, 3)
    z = camera.to_camera_frame(flat)[:, 2].reshape(n, k)
    uv = camera.project_or_nan(flat).reshape(n, k, 2)
    w, h = camera.image_size
    inside = (
        (uv[..., 0] >= IMAGE_MARGIN)
        & (uv[..., 0] <= w - 1 - IMAGE_MARGIN)
        & (uv[..., 1] >= IMAGE_MARGIN)
        & (uv[..., 1] <= h - 1 - IMAGE_MARGIN)
    )
    return np.flatnonzero((z > 0.1).all(axis=1) & inside.all(axis=1)), uv


def _leds_seen(
    scenario: Scenario,
    cam: NDArray[np.float64],
    led_w: NDArray[np.float64],
    parent_xy: NDArray[np.float64],
    anchor_xy: NDArray[np.float64] | None,
) -> NDArray[np.bool_]:
    """(N,) whether the camera at ``cam`` ((3,) m) sees all (N, K, 3) LEDs of each
    candidate past the map's obstacles, the parent and the anchor child ((2,) m or None)."""
    n, k = led_w.shape[:2]
    flat = led_w.reshape(-1, 3)
    floor = scenario.space.floor_z
    hidden = ~sight_clear(scenario, cam, flat)
    hidden |= passes_near(cam, flat, parent_xy, parent_profile(floor))
    if anchor_xy is not None:
        hidden |= passes_near(cam, flat, anchor_xy, child_profile(floor))
    return ~hidden.reshape(n, k).any(axis=1)


def _prisms_seen(
    scenario: Scenario,
    inst: NDArray[np.float64],
    cube_w: NDArray[np.float64],
    anchor_xy: NDArray[np.float64] | None,
) -> NDArray[np.bool_]:
    """(N,) whether the instrument at ``inst`` ((3,) m) has all (N, K, 3) prisms of each
    candidate in range (with ``RANGE_MARGIN``) and in sight past the map's obstacles and
    the anchor child ((2,) m or None)."""
    n, k = cube_w.shape[:2]
    ts = scenario.noise.total_station
    d = np.linalg.norm(cube_w - inst, axis=-1)
    ok = (d.min(axis=1) >= ts.range_min + RANGE_MARGIN) & (d.max(axis=1) <= ts.range_max)
    flat = cube_w.reshape(-1, 3)
    hidden = ~sight_clear(scenario, inst, flat)
    if anchor_xy is not None:
        hidden |= passes_near(inst, flat, anchor_xy, child_profile(scenario.space.floor_z))
    return ok & ~hidden.reshape(n, k).any(axis=1)


def _farthest_first(feats: NDArray[np.float64], start: NDArray[np.float64]) -> list[int]:
    """Farthest-point order of (N, D) features, first the one nearest ``start``."""
    n = len(feats)
    first = int(np.argmin(_norms(feats - start)))
    order = [first]
    dist = _norms(feats - feats[first])
    dist[first] = -1.0
    while len(order) < n:
        k = int(np.argmax(dist))
        order.append(k)
        # Chosen features stay at -1: every distance is >= 0.
        dist = np.minimum(dist, _norms(feats - feats[k]))
        dist[k] = -1.0
    return order


def _norms(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N,) Euclidean norms of (N, D) rows, as ``np.linalg.norm(v, axis=1)`` computes them."""
    return np.sqrt(np.add.reduce(v * v, axis=1))


def tour(stops: list[ViewStop], start_xy: ArrayLike) -> list[ViewStop]:
    """The stops reordered as a nearest-neighbour tour from ``start_xy`` (less driving)."""
    left = list(stops)
    here = np.asarray(start_xy, dtype=float).reshape(2)
    out = []
    while left:
        k = int(np.argmin([np.linalg.norm(s.stop.xy - here) for s in left]))
        out.append(left.pop(k))
        here = out[-1].stop.xy
    return out
