"""Where the two children stop during a CPS leg: ahead of the parent's next station,
staggered sideways, in sight and in range of the instrument at both of the parent's
stations.

Planned on the map and the campaign's estimates; nothing is measured here.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from calib.rotation import wrap_angle
from twin.campaign.plan.clearance import (
    CHILD_BODY,
    PARENT_BODY,
    in_range,
    robot_fits,
    sight_clear,
)
from twin.campaign.plan.formation_checks import (
    FORMATION_CLEARANCE,
    MIN_SEPARATION,
    FormationChecks,
)
from twin.campaign.plan.occlusion import unhidden_yaw
from twin.campaign.plan.route import RoutePath
from twin.campaign.plan.stop import Stop
from twin.scenario.schema import FormationSettings, Space

SIGHT_MARGIN = 0.10
"""A formation's lines of sight pass obstacles by at least this much, m: a child stops
centimetres from its goal (further on wheel odometry), and a prism planned to graze a
corner would be hidden."""

UNCERTAINTY_SIGMAS = 2.0
"""Standard deviations of the parent's position estimate that a formation's lines of sight
keep from obstacles, where that is more than :data:`SIGHT_MARGIN`."""

STEPPED_SIGMAS = (UNCERTAINTY_SIGMAS, 1.0)
"""The standard deviations a formation's lines of sight keep, tried in turn where more than
:data:`SIGHT_MARGIN`: where a corner leaves no room for two, one is still worth keeping."""


def sight_margins(parent_std: float) -> tuple[float, ...]:
    """The sight margins a formation tries, in turn, m: the widest first,
    :data:`SIGHT_MARGIN` last (where nothing else fits).

    The group is planned where CPS believes it stands; after a long travel the whole group
    truly stands off that by about the parent's position error (the children are placed
    from the parent), and a line of sight planned to pass a corner by :data:`SIGHT_MARGIN`
    grazes it in truth. Where :data:`UNCERTAINTY_SIGMAS` times the parent's horizontal
    position standard deviation is more than that, it is tried first, then one standard
    deviation (:data:`STEPPED_SIGMAS`) where that is more too.

    Args:
        parent_std: the parent's horizontal position standard deviation along its most
            uncertain axis, m (:attr:`twin.localization.pose.ParentPose.horizontal_std`).
    """
    wider = [n * parent_std for n in STEPPED_SIGMAS if n * parent_std > SIGHT_MARGIN]
    return (*wider, SIGHT_MARGIN)


def _instrument(xy: ArrayLike, instrument_z: float) -> NDArray[np.float64]:
    p = np.asarray(xy, dtype=float).reshape(2)
    return np.array([p[0], p[1], instrument_z])


def formation(
    space: Space,
    cubes_body: ArrayLike,
    instrument_range: tuple[float, float],
    path: RoutePath,
    s_next: float,
    parent_now: ArrayLike,
    parent_next: ArrayLike,
    direction: float,
    form: FormationSettings,
    instrument_z: float,
    waiting_xy: ArrayLike | None = None,
    margins: tuple[float, ...] = (SIGHT_MARGIN,),
) -> tuple[int, list[Stop]] | None:
    """Stops of the two children ahead of the parent's next station.

    The children stand ahead (in the direction of travel, ``direction`` = +1 or -1 along the
    path) of ``s_next``, staggered sideways; each must be free, in range and in sight of the
    instrument at both the parent's current and next stations, and the two must be at least
    ``MIN_SEPARATION`` apart seen from both. Smaller, mirrored and zero offsets and shorter
    gaps are tried in turn.

    Args:
        space: the map. cubes_body: (3, 3) the marker's prisms in the child's body frame, m.
        instrument_range: the total station's (least, greatest) distance, m.
        path: the route. s_next: the parent's next station's arc length on it, m.
        parent_now, parent_next: (2,) the parent's current and next station, m.
        direction: +1 or -1, the direction of travel along the path.
        form: the formation's settings. instrument_z: the instrument's height in W, m.
        waiting_xy: (2,) where the other child stands while the far one is measured from
            the current station (it moves second), m; it must not hide the far child's
            prisms.
        margins: how far the lines of sight pass obstacles, m, the first that any
            placement keeps being the one kept (see :func:`sight_margins`): as if each were
            tried in turn, in one pass over the placements.

    Returns:
        The index of the margin kept in ``margins``, and the stops (the far child's first:
        it moves first); or None.
    """
    cubes = np.asarray(cubes_body, dtype=float)
    stations = [_instrument(parent_now, instrument_z), _instrument(parent_next, instrument_z)]
    gaps = [form.near_gap, 0.75 * form.near_gap + 0.5, 2.0]
    lat = form.lateral
    # (near, far) sideways offsets: staggered either way, then both to one side.
    sides = [(lat, -lat), (-lat, lat), (0.5 * lat, -0.5 * lat), (-0.5 * lat, 0.5 * lat)]
    sides += [(a * lat, b * lat) for a, b in ((0, -1), (0, 1), (-1, 0), (1, 0), (-1.5, -0.3))]
    sides += [(a * lat, b * lat) for a, b in ((1.5, 0.3), (-0.3, -1.5), (0.3, 1.5))]
    sides += [(0.3, -0.3), (-0.3, 0.3), (0.15, -0.15), (-0.15, 0.15)]  # narrow corridors
    checks = FormationChecks(space, cubes, stations, instrument_range, waiting_xy)
    best: tuple[int, list[Stop]] | None = None  # the first placement keeping margins[k]
    for gap in gaps:
        for spacing in (form.spacing, 0.7 * form.spacing):
            for near_side, far_side in sides:
                # The places repeat over the sides and spacings: each is checked once.
                far = checks.spot(path, s_next, direction, gap + spacing, far_side)
                near = checks.spot(path, s_next, direction, gap, near_side)
                if not (checks.free(far[0]) and checks.free(near[0])):
                    continue
                if np.linalg.norm(far[0] - near[0]) < 1.0:
                    continue
                # Where the children stand decides most; their headings cost more to find.
                tried = margins[: len(margins) if best is None else best[0]]
                first = checks.turned(*far)
                if first is None or not any(checks.alone_ok(first, m, True) for m in tried):
                    continue  # every heading hides a prism from a station, or it is unseen
                second = checks.turned(*near)
                if second is None:
                    continue
                stops = [first, second]
                for k in range(len(tried)):
                    if checks.pair_ok(stops, margins[k]):
                        if k == 0:
                            return k, stops
                        best = (k, stops)
                        break
    return best


CORNER_REACH = 6.0
"""How far from the parent's next station the children may stand in a formation around a
corner, m (:func:`corner_formation`)."""

CORNER_PITCH = 0.35
"""Spacing of the places tried for a child around a corner, m."""

CORNER_AHEAD = 4.0
"""Progress along the route beyond the parent's next station that counts, m: a child
farther ahead than this is as good as one this far ahead."""

CORNER_PAIRS = 30
"""The places tried as the first-moving child's stop around a corner, best first."""

PASSING = PARENT_BODY + CHILD_BODY + 0.1
"""Distance a child's stop keeps from the parent's drive, m (the two radii and a margin)."""


def corner_formation(
    space: Space,
    cubes_body: ArrayLike,
    instrument_range: tuple[float, float],
    path: RoutePath,
    s_next: float,
    parent_way: ArrayLike,
    direction: float,
    instrument_z: float,
    waiting_xy: ArrayLike | None = None,
    margins: tuple[float, ...] = (SIGHT_MARGIN,),
) -> tuple[int, list[Stop]] | None:
    """Stops of the two children anywhere both of the parent's stations see, where the
    staggered formation ahead of the next station (:func:`formation`) has none: around a
    turn its places lie round the corner, hidden from where the parent stands now.

    The places tried lie on a grid (:data:`CORNER_PITCH`) within :data:`CORNER_REACH` of
    the next station, free, in range and in sight of both stations, and clear of the
    parent's drive (:data:`PASSING`); the pair is the one farthest ahead along the route
    (up to :data:`CORNER_AHEAD` beyond the next station) that suits both stations as
    :func:`formation`'s does, the one farther ahead moving first.

    Args:
        space, cubes_body, instrument_range, path, s_next, direction, instrument_z,
            waiting_xy, margins: as :func:`formation`.
        parent_way: (K >= 2, 2) the parent's drive from its station to the next, m.

    Returns:
        The index of the margin kept in ``margins`` and the stops (the first-moving
        child's first); or None.
    """
    cubes = np.asarray(cubes_body, dtype=float)
    way = np.asarray(parent_way, dtype=float).reshape(-1, 2)
    stations = [_instrument(way[0], instrument_z), _instrument(way[-1], instrument_z)]
    n = int(CORNER_REACH / CORNER_PITCH)
    axis = CORNER_PITCH * np.arange(-n, n + 1)
    gx, gy = np.meshgrid(axis, axis)
    xy = way[-1] + np.column_stack([gx.ravel(), gy.ravel()])
    xy = xy[np.linalg.norm(xy - way[-1], axis=1) <= CORNER_REACH]
    xy = xy[robot_fits(space, xy, FORMATION_CLEARANCE)]
    for inst in stations:
        xy = xy[np.linalg.norm(xy - inst[:2], axis=1) >= 1.0]
    xy = xy[_distance_to_polyline(xy, way) >= PASSING]
    if len(xy) < 2:
        return None
    # Seen from both stations at the prisms' mean height (the headings come later).
    top = np.column_stack([xy, np.full(len(xy), space.floor_z + float(cubes[:, 2].mean()))])
    for inst in stations:
        d = np.linalg.norm(top - inst, axis=1)
        seen = in_range(d, instrument_range) & sight_clear(space, inst, top, margins[-1])
        xy, top = xy[seen], top[seen]
    if len(xy) < 2:
        return None
    arc = [path.project(p, near=s_next) for p in xy]
    ahead = np.array([direction * (s - s_next) for s in arc])
    off = np.array([np.linalg.norm(path.at(s) - p) for s, p in zip(arc, xy, strict=True)])
    score = np.minimum(ahead, CORNER_AHEAD) - 0.25 * off
    order = np.argsort(-score, kind="stable")
    stops: list[Stop | None] = [None] * len(xy)

    def stop_at(i: int) -> Stop | None:
        if stops[i] is None:
            s = arc[i]
            yaw = path.heading(s) + (0.0 if direction > 0 else math.pi)
            turned = unhidden_yaw(xy[i], yaw, cubes, stations, space.floor_z)
            stops[i] = Stop(xy[i], turned) if turned is not None else Stop(xy[i], math.nan)
        found = stops[i]
        return None if found is None or math.isnan(found.yaw) else found

    # What a pair needs of its places alone, as arrays: 1 m apart, apart in bearing.
    apart = np.linalg.norm(xy[:, None] - xy[None], axis=-1) >= 1.0
    for inst in stations:
        bearing = np.arctan2(xy[:, 1] - inst[1], xy[:, 0] - inst[0])
        apart &= np.abs(wrap_angle(bearing[:, None] - bearing[None])) >= MIN_SEPARATION
    checks = FormationChecks(space, cubes, stations, instrument_range, waiting_xy)
    for k, margin in enumerate(margins):
        for i in order[:CORNER_PAIRS]:
            far = stop_at(int(i))
            if far is None:
                continue
            partners = [j for j in order if apart[i, j] and score[j] <= score[i]]
            for j in partners[:CORNER_PAIRS]:
                near = stop_at(int(j))
                if near is None:
                    continue
                pair = [far, near]
                if checks.pair_ok(pair, margin):
                    return k, pair
    return None


def _distance_to_polyline(points: NDArray[np.float64], line: NDArray[np.float64]) -> NDArray:
    """(N,) least distance of (N, 2) points from the (K >= 2, 2) polyline, m."""
    out = np.full(len(points), math.inf)
    for a, b in itertools.pairwise(line):
        d = b - a
        n2 = max(float(d @ d), 1e-12)
        t = np.clip((points - a) @ d / n2, 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(a + t[:, None] * d - points, axis=1))
    return out
