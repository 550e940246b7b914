"""Where a child stops in a camera's view for the camera's data: every place that shows all
its LEDs to the camera and its prisms to the total station, in an order that spreads any
first few over the view, and the tour that visits them.

Planned on the map (the camera's nominal pose) and the campaign's estimates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera
from twin.campaign.plan.clearance import (
    body_points,
    child_profile,
    in_range,
    parent_profile,
    passes_near,
    robot_fits,
    sight_clear,
)
from twin.campaign.plan.stop import Stop
from twin.instruments.marker import MarkerAssembly
from twin.scenario.geometry import floor_view
from twin.scenario.schema import Space

IMAGE_MARGIN = 12.0
"""The planned LED pixels stay this far inside the image, px, so that a child that stops a
few centimetres off still shows all four LEDs."""


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
    space: Space,
    marker: MarkerAssembly,
    instrument_range: tuple[float, float],
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
        space: the map. marker: the child's assembly (LEDs and prisms, body frame).
        instrument_range: the total station's (least, greatest) distance, m.
        camera: the camera's nominal model (world frame).
        parent_xy: the parent's position, m. instrument_z: the instrument's height in W, m.
        anchor_xy: the other child's position (it stays), m, or None.
    """
    found = candidate_places(space, marker, camera, parent_xy, anchor_xy, grid)
    if found is None:
        return []
    xy, yaw, idx, led_w, cube_w = found.xy, found.yaw, found.idx, found.led_w, found.cube_w
    cam = camera.position
    parent = np.asarray(parent_xy, dtype=float).reshape(2)
    anchor = None if anchor_xy is None else np.asarray(anchor_xy, float).reshape(2)
    inst = np.array([parent[0], parent[1], instrument_z])
    # Each test on the candidates that passed the ones before (the cheap ones first).
    sel, pix = leds_in_image(camera, led_w)
    sel = sel[~leds_hidden(space, cam, led_w[sel], parent, anchor).any(axis=1)]
    sel = sel[prisms_seen(space, instrument_range, inst, cube_w[sel], anchor)]
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
    order = farthest_first(feats, start=np.array([0.5, 0.5, 0.5]))
    return [ViewStop(Stop(xy[keep[k]].copy(), float(yaw[keep[k]])), pix[k]) for k in order]


@dataclass(frozen=True)
class CandidatePlaces:
    """Where a child could stand in a camera's view, before the visibility tests.

    Attributes:
        xy: (M, 2) sampled places, m. yaw: (M,) the child's heading there, facing the
            camera, rad. idx: (N,) the places where the child fits, clear of the parent
            and the anchor. led_w, cube_w: (N, K, 3) its LEDs and prisms in W there, m.
    """

    xy: NDArray[np.float64]
    yaw: NDArray[np.float64]
    idx: NDArray[np.intp]
    led_w: NDArray[np.float64]
    cube_w: NDArray[np.float64]


def candidate_places(
    space: Space,
    marker: MarkerAssembly,
    camera: TsaiCamera,
    parent_xy: ArrayLike,
    anchor_xy: ArrayLike | None,
    grid: int = 40,
) -> CandidatePlaces | None:
    """The places of :func:`view_stops` where the child fits, facing ``camera``, clear of
    the walls, the obstacles, the parent and the anchor child (None: no place)."""
    floor = space.floor_z
    leds = marker.leds_body
    cubes = marker.cubes_body
    # Where the image's rays meet planes at the LEDs' heights: a steep camera sees the top
    # LED only far beyond where it sees the floor.
    heights = np.linspace(0.0, float(leds[:, 2].max()), 4)
    ground = np.vstack([floor_view(camera, floor + z, 40.0, grid // 2) for z in heights])
    if len(ground) == 0:
        return None
    xy = ground[:, :2]
    cam = camera.position
    yaw = np.arctan2(cam[1] - xy[:, 1], cam[0] - xy[:, 0])
    # The mast is at the body origin and the LEDs stand in front of it: move the body back
    # so that the mast, not the body origin, is where the image row points.
    ok = robot_fits(space, xy)
    parent = np.asarray(parent_xy, dtype=float).reshape(2)
    ok &= np.linalg.norm(xy - parent, axis=1) > 1.2
    anchor = None if anchor_xy is None else np.asarray(anchor_xy, float).reshape(2)
    if anchor is not None:
        ok &= np.linalg.norm(xy - anchor, axis=1) > 1.2
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None
    led_w = body_points(xy[idx], yaw[idx], leds, floor)
    cube_w = body_points(xy[idx], yaw[idx], cubes, floor)
    return CandidatePlaces(xy, yaw, idx, led_w, cube_w)


def leds_in_image(
    camera: TsaiCamera, led_w: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Which of N candidates' (N, K, 3) LEDs (W, m) all lie more than 0.1 m in front of
    the camera and project inside its image with ``IMAGE_MARGIN``.

    Returns:
        (M,) indices of those candidates, and (N, K, 2) every candidate's pixels (NaN
        where an LED cannot be projected), px.
    """
    each, uv = each_led_in_image(camera, led_w)
    return np.flatnonzero(each.all(axis=1)), uv


def each_led_in_image(
    camera: TsaiCamera, led_w: NDArray[np.float64]
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """(N, K) whether each of N candidates' (N, K, 3) LEDs (W, m) lies more than 0.1 m in
    front of the camera and projects inside its image with ``IMAGE_MARGIN``, and (N, K, 2)
    their pixels (NaN where an LED cannot be projected), px."""
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
    return (z > 0.1) & inside, uv


def leds_hidden(
    space: Space,
    cam: NDArray[np.float64],
    led_w: NDArray[np.float64],
    parent_xy: NDArray[np.float64],
    anchor_xy: NDArray[np.float64] | None,
) -> NDArray[np.bool_]:
    """(N, K) whether the map's obstacles, the parent or the anchor child ((2,) m or None)
    hide each of (N, K, 3) LEDs from the camera at ``cam`` ((3,) m)."""
    n, k = led_w.shape[:2]
    flat = led_w.reshape(-1, 3)
    floor = space.floor_z
    hidden = ~sight_clear(space, cam, flat)
    hidden |= passes_near(cam, flat, parent_xy, parent_profile(floor))
    if anchor_xy is not None:
        hidden |= passes_near(cam, flat, anchor_xy, child_profile(floor))
    return hidden.reshape(n, k)


def prisms_seen(
    space: Space,
    instrument_range: tuple[float, float],
    inst: NDArray[np.float64],
    cube_w: NDArray[np.float64],
    anchor_xy: NDArray[np.float64] | None,
) -> NDArray[np.bool_]:
    """(N,) whether the instrument at ``inst`` ((3,) m) has all (N, K, 3) prisms of each
    candidate in range (:func:`in_range`) and in sight past the map's obstacles and
    the anchor child ((2,) m or None)."""
    n, k = cube_w.shape[:2]
    d = np.linalg.norm(cube_w - inst, axis=-1)
    ok = in_range(d, instrument_range).all(axis=1)
    flat = cube_w.reshape(-1, 3)
    hidden = ~sight_clear(space, inst, flat)
    if anchor_xy is not None:
        hidden |= passes_near(inst, flat, anchor_xy, child_profile(space.floor_z))
    return ok & ~hidden.reshape(n, k).any(axis=1)


def farthest_first(feats: NDArray[np.float64], start: NDArray[np.float64]) -> list[int]:
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


_S = TypeVar("_S", bound=ViewStop)


def tour(stops: list[_S], start_xy: ArrayLike) -> list[_S]:
    """The stops reordered as a nearest-neighbour tour from ``start_xy`` (less driving)."""
    left = list(stops)
    here = np.asarray(start_xy, dtype=float).reshape(2)
    out = []
    while left:
        k = int(np.argmin([np.linalg.norm(s.stop.xy - here) for s in left]))
        out.append(left.pop(k))
        here = out[-1].stop.xy
    return out
