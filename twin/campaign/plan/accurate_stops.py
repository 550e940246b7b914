"""Where a child stops in a camera's view for an accurate calibration (``campaign.data_stops
= "accuracy"``): every place that shows at least one LED to the camera (and all prisms to
the total station), chosen greedily to make the calibrated camera's position precise.

:func:`twin.campaign.plan.view_stops.view_stops` keeps only places that show all four LEDs;
on a steep camera those lie in a narrow band at the far edge of the view, and the data lack
depth. Here a place counts with the LEDs it shows, and the stops are chosen to lower the
predicted covariance of the camera's optical centre (Tsai's model at the camera's nominal
pose): each LED weighs with its pixel noise plus its 3D point's error (the total station's
at that range) projected into the image, so that far stops, whose points the image sees
sharply but the instrument measures no better, are not over-valued.

Planned on the map (the camera's nominal pose) and the campaign's estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.point_errors import position_covariance_from_blocks
from calib.tsai import pixel_jacobian, predicted_covariance
from twin.campaign.plan.stop import Stop
from twin.campaign.plan.view_stops import (
    ViewStop,
    candidate_places,
    each_led_in_image,
    farthest_first,
    leds_hidden,
    prisms_seen,
)
from twin.instruments.marker import MarkerAssembly
from twin.instruments.total_station import TotalStationSpec
from twin.scenario.schema import Space

PLAN_PIXEL_PX = 0.05
"""The LED pixel noise the plan assumes, px per coordinate: what the twin's detector
achieves on its images (``noise.led_detection_px``'s default). A strategy does not read the
twin's simulated noise."""

SEED_POINTS = 12
"""The spread first stops hold at least this many LED points before the greedy choice."""

SEED_CONDITION = 1e8
"""...and the Fisher information of Tsai's parameters from them (scaled to a unit diagonal)
has a condition number below this."""


@dataclass(frozen=True)
class AccurateStop(ViewStop):
    """A planned stop that may show only some of the child's LEDs.

    Attributes:
        stop, pixels: as :class:`ViewStop` (pixels of the LEDs not shown may lie outside
            the image or be NaN).
        shown: (N_led,) which LEDs the camera is expected to see from here.
        leds_world: (N_led, 3) the LEDs in W at the stop (the child facing the camera), m.
    """

    shown: NDArray[np.bool_]
    leds_world: NDArray[np.float64]

    @property
    def points(self) -> int:
        """LED points the stop is expected to give."""
        return int(self.shown.sum())


def partial_view_stops(
    space: Space,
    marker: MarkerAssembly,
    instrument_range: tuple[float, float],
    camera: TsaiCamera,
    parent_xy: ArrayLike,
    instrument_z: float,
    anchor_xy: ArrayLike | None,
    grid: int = 40,
) -> list[AccurateStop]:
    """The places of :func:`~twin.campaign.plan.view_stops.view_stops` with the same
    tests, but a place is kept when at least one LED (not all) projects inside the image
    with the margin and is not hidden; each records the LEDs it shows. In farthest-point
    order of (image column, image row, distance) of the shown LEDs, as ``view_stops``.
    """
    found = candidate_places(space, marker, camera, parent_xy, anchor_xy, grid)
    if found is None:
        return []
    xy, yaw, idx, led_w, cube_w = found.xy, found.yaw, found.idx, found.led_w, found.cube_w
    cam = camera.position
    parent = np.asarray(parent_xy, dtype=float).reshape(2)
    anchor = None if anchor_xy is None else np.asarray(anchor_xy, float).reshape(2)
    inst = np.array([parent[0], parent[1], instrument_z])
    shown, pix = each_led_in_image(camera, led_w)
    sel = np.flatnonzero(shown.any(axis=1))
    shown[sel] &= ~leds_hidden(space, cam, led_w[sel], parent, anchor)
    sel = sel[shown[sel].any(axis=1)]
    sel = sel[prisms_seen(space, instrument_range, inst, cube_w[sel], anchor)]
    if sel.size == 0:
        return []
    keep = idx[sel]
    shown, pix, led_w = shown[sel], pix[sel], led_w[sel]
    w, h = camera.image_size
    depth = np.linalg.norm(xy[keep] - cam[:2], axis=1)
    count = shown.sum(axis=1)
    mean = np.where(shown[..., None], np.nan_to_num(pix), 0.0).sum(axis=1) / count[:, None]
    feats = np.column_stack(
        [mean[:, 0] / w, mean[:, 1] / h, (depth - depth.min()) / max(np.ptp(depth), 1e-9)]
    )
    order = farthest_first(feats, start=np.array([0.5, 0.5, 0.5]))
    return [
        AccurateStop(
            Stop(xy[keep[k]].copy(), float(yaw[keep[k]]), tuple(np.flatnonzero(shown[k]).tolist())),
            pix[k],
            shown[k],
            led_w[k],
        )
        for k in order
    ]


def point_covariance(
    points: ArrayLike, instrument: ArrayLike, spec: TotalStationSpec
) -> NDArray[np.float64]:
    """(..., 3, 3) covariance of LED points (..., 3) in W, m, measured by the total station
    at ``instrument`` ((3,) m): the distance's noise along the line of sight, the angles'
    across it and the aim's pointing error on every axis, m^2 (each point as one shot; the
    parent's own pose error, common to a station, is left out)."""
    p = np.asarray(points, dtype=float)
    v = p - np.asarray(instrument, dtype=float).reshape(3)
    d = np.linalg.norm(v, axis=-1)
    u = v / np.maximum(d, 1e-9)[..., None]
    along = (spec.distance_sigma_const + spec.distance_sigma_ppm * 1e-6 * d) ** 2
    across = (spec.angle_sigma * d) ** 2
    uu = u[..., :, None] * u[..., None, :]
    eye = np.eye(3)
    return (
        along[..., None, None] * uu
        + across[..., None, None] * (eye - uu)
        + spec.pointing_sigma**2 * eye
    )


def predicted_position_covariance(
    camera: TsaiCamera,
    points: ArrayLike,
    instrument: ArrayLike,
    spec: TotalStationSpec,
    pixel_px: float = PLAN_PIXEL_PX,
) -> NDArray[np.float64]:
    """(3, 3) predicted covariance of the optical centre, m^2, of a calibration on (N, 3)
    LED points: the Cramer-Rao bound for ``pixel_px`` of pixel noise
    (:func:`calib.tsai.predicted_covariance`) plus the first-order effect of the points'
    own errors (:func:`point_covariance`, independent points;
    :func:`calib.point_errors.position_covariance_from_blocks`)."""
    p3 = np.asarray(points, dtype=float).reshape(-1, 3)
    pixel = predicted_covariance(camera, p3, pixel_px)[8:11, 8:11]
    blocks = point_covariance(p3, instrument, spec)
    own = position_covariance_from_blocks(
        TsaiCameras.from_cameras([camera]), p3[None], blocks[None]
    )[0]
    return pixel + own


def choose_stops(
    candidates: list[AccurateStop],
    camera: TsaiCamera,
    instrument: ArrayLike,
    spec: TotalStationSpec,
    points: int,
    pixel_px: float = PLAN_PIXEL_PX,
) -> tuple[list[AccurateStop], list[AccurateStop]]:
    """The stops to take ``points`` LED points at, and the spares, in order.

    The first stops are the candidates' first (spread over the view and depth), until they
    hold ``SEED_POINTS`` LED points and make the Fisher information of Tsai's 11
    parameters well conditioned. Then, one at a time, the candidate whose LEDs most lower
    the trace of the optical centre's block of the inverse Fisher information (per stop,
    not per LED point: a stop costs its drive and its measurements, nearly the same for
    one LED as for four; per point the choice takes about twice the stops for a few
    per cent less variance); each LED weighs with the inverse of its pixel noise
    ``pixel_px`` plus its 3D error (:func:`point_covariance`) projected into the image.
    The information of a stop is a sum of rank-2 terms (one per LED), so each step updates
    the inverse with the Woodbury identity. The planned stops end where they hold
    ``points`` LED points; the spares are the next greedy choices (as many points again),
    then the rest in the candidates' order.

    Args:
        candidates: from :func:`partial_view_stops`, in its order.
        camera: the camera's nominal model. instrument: (3,) the total station in W, m.
        spec: the total station's specification. points: LED points wanted.
        pixel_px: the LEDs' pixel noise, px.

    Returns:
        (planned stops, spare stops).
    """
    n = len(candidates)
    if n == 0:
        return [], []
    k = len(candidates[0].shown)
    shown = np.array([c.shown for c in candidates])
    leds = np.array([c.leds_world for c in candidates])
    count = shown.sum(axis=1)
    g = _whitened_jacobians(camera, leds, shown, instrument, spec, pixel_px)
    # Scale the parameters to a unit diagonal of the whole candidate set's information.
    scale = np.sqrt(np.einsum("nri,nri->i", g, g))
    scale = np.where(scale > 0, scale, 1.0)
    g = g / scale
    # The spread seeds.
    info = np.zeros((11, 11))
    chosen: list[int] = []
    for i in range(n):
        chosen.append(i)
        info += g[i].T @ g[i]
        if count[chosen].sum() >= SEED_POINTS and np.linalg.cond(_unit(info)) < SEED_CONDITION:
            break
    else:
        return _split(candidates, list(range(n)), points)
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    left = np.ones(n, dtype=bool)
    left[chosen] = False
    eye = np.eye(2 * k)
    weight = 1.0 / scale[8:11]
    while left.any() and count[chosen].sum() < 2 * points:
        idx = np.flatnonzero(left)
        gp = g[idx] @ cov  # (m, 2k, 11)
        s = eye + gp @ np.swapaxes(g[idx], 1, 2)
        b = gp[:, :, 8:11] * weight
        gain = np.einsum("mrj,mrj->m", b, np.linalg.solve(s, b))
        best = int(np.argmax(gain))
        c = idx[best]
        cov -= gp[best].T @ np.linalg.solve(s[best], gp[best])
        cov = 0.5 * (cov + cov.T)
        chosen.append(int(c))
        left[c] = False
    chosen += [int(i) for i in np.flatnonzero(left)]
    return _split(candidates, chosen, points)


def _split(
    candidates: list[AccurateStop], order: list[int], points: int
) -> tuple[list[AccurateStop], list[AccurateStop]]:
    """The candidates in ``order``: those until ``points`` LED points, and the rest."""
    total = np.cumsum([candidates[i].points for i in order])
    need = int(np.searchsorted(total, points)) + 1
    return [candidates[i] for i in order[:need]], [candidates[i] for i in order[need:]]


def _unit(info: NDArray[np.float64]) -> NDArray[np.float64]:
    """A symmetric matrix scaled to a unit diagonal (zeros kept)."""
    d = np.sqrt(np.diag(info))
    d = np.where(d > 0, d, 1.0)
    return info / np.outer(d, d)


def _whitened_jacobians(
    camera: TsaiCamera,
    leds: NDArray[np.float64],
    shown: NDArray[np.bool_],
    instrument: ArrayLike,
    spec: TotalStationSpec,
    pixel_px: float,
) -> NDArray[np.float64]:
    """(N, 2K, 11) each candidate's pixel Jacobian (Tsai's internal parameters,
    :func:`calib.tsai.pixel_jacobian`) whitened LED by LED with the inverse Cholesky
    factor of its pixel covariance (``pixel_px`` plus its point's error projected); zero
    rows for the LEDs it does not show."""
    n, k = shown.shape
    jac = pixel_jacobian(camera, leds.reshape(-1, 3)).reshape(n, k, 2, 11)
    grad = -jac[..., 8:11]  # d pixel / d point
    cov = grad @ point_covariance(leds, instrument, spec) @ np.swapaxes(grad, -1, -2)
    cov = cov + max(pixel_px, 1e-6) ** 2 * np.eye(2)
    white = np.linalg.solve(np.linalg.cholesky(cov), jac)
    white = np.where(shown[..., None, None], white, 0.0)
    return white.reshape(n, 2 * k, 11)
