"""Where the parent stands for each camera: a station from which the total station sees
the child anywhere in the camera's floor view, reachable with the parent's clearance.

Candidates lie on a grid over the reachable floor, within a band of distances from the
camera's floor view; each is scored by :func:`twin.scenario.visibility.stations_visibility`
(the fraction of the view's floor whose prisms the instrument sees, in range and clear of
obstacles), the same test the scenario's validation applies to a station. The station is
the candidate that sees the most, the nearest to a preferred distance from the view among
equals (the paper's stations stand 4-8 m from their cameras' views). Every other grid
point is scored first, then the neighbours of the best (:func:`_scored`): a score costs a
line of sight to each sample of the view, and it changes little over a grid step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import Point
from shapely.geometry.base import BaseGeometry

from calib.camera import TsaiCamera
from twin.campaign.plan.clearance import CHILD_BODY, PARENT_BODY
from twin.campaign.plan.ways import ROBOT_MARGIN
from twin.scenario.geometry import floor_view
from twin.scenario.schema import Space
from twin.scenario.visibility import stations_visibility

GRID = 0.5
"""Spacing of the candidate stations, m."""

NEAREST, FARTHEST = 2.0, 12.0
"""Band of distances from the view's centre in which stations are sought, m."""

PREFERRED = 5.0
"""Distance from the view's centre a station is preferred at among equals, m."""

MOST_TRIED = 40
"""How many of the best candidates :func:`choose_station` asks for data stops before it
gives up on a camera (each asks the planner of stops once)."""

REFINED = 10
"""How many of the best candidates of the coarse grid (every other point) have their
neighbours scored too (:func:`_scored`)."""

COARSE_FROM = 4 * MOST_TRIED
"""Fewer candidates than this are all scored at once."""

REACHED = 2
"""What ``gives_data`` of :func:`choose_station` says of a station whose data stops the
children reach."""

SEES_EQUALLY = 0.02
"""Two candidates whose visible fractions differ by less than this see equally well."""


AVOID_RADIUS = 2.0
"""How far a station keeps from a place it is told to avoid, m: about the formation's reach
(the children stand 2.5 m and more ahead), so that the new station is not the old one's
neighbour on the grid."""


@dataclass(frozen=True)
class Station:
    """A camera's station.

    Attributes:
        camera: the camera's name. xy: (2,) the station in W, m.
        visible: the fraction of the camera's floor view the instrument sees from it.
        view_centre: (2,) the centre of the camera's floor view in W, m.
    """

    camera: str
    xy: NDArray[np.float64]
    visible: float
    view_centre: NDArray[np.float64]


class NoStationError(ValueError):
    """No reachable place sees enough of a camera's view: the message names the camera,
    the best fraction found and where; ``best`` is that place (None where there is none)."""

    def __init__(self, message: str, best: Station | None = None) -> None:
        super().__init__(message)
        self.best = best


def choose_station(
    camera_name: str,
    camera: TsaiCamera,
    space: Space,
    reachable: BaseGeometry,
    *,
    instrument_z: float,
    prism_height: float,
    instrument_range: tuple[float, float],
    need: float,
    grid: float = GRID,
    avoid: NDArray[np.float64] | None = None,
    gives_data: Callable[[NDArray[np.float64]], int] | None = None,
) -> Station:
    """The station of one camera (see the module).

    Args:
        camera_name: its name. camera: its nominal model in W.
        space: the scenario's space (the blocked boxes hide the view).
        reachable: where the parent's centre may stand, W.
        instrument_z: the instrument's height in W, m. prism_height: the prisms' height
            above the floor, m. instrument_range: the instrument's (least, greatest)
            distance, m.
        need: the least visible fraction a station must reach.
        grid: candidates' spacing, m.
        avoid: (K, 2) places in W no station may stand within :data:`AVOID_RADIUS` of
            (where an earlier plan's station or travel failed); default none.
        gives_data: whether a child finds its data stops in the camera's view with the
            parent at a (2,) station in W (the campaign's own planner of stops): 0 or
            False where none, :data:`REACHED` where the children reach them past the
            standing parent (:func:`stops_reached`), 1 or True where they may not. The
            first candidate of :data:`REACHED` is taken, else the first that gives data;
            one that gives none is passed over (default: every one gives data).

    Raises:
        NoStationError: no candidate reaches ``need`` (and gives data).
    """
    view = floor_view(camera, space.floor_z, max_range=60.0)
    if len(view) == 0:
        raise NoStationError(f"camera {camera_name!r} sees no floor")
    centre = view[:, :2].mean(axis=0)
    candidates = _candidates(reachable, centre, grid)
    if avoid is not None and len(avoid) and len(candidates):
        near = np.linalg.norm(candidates[:, None, :] - np.asarray(avoid)[None, :, :], axis=2)
        candidates = candidates[np.all(near >= AVOID_RADIUS, axis=1)]
    fractions = _scored(
        candidates,
        centre,
        grid,
        lambda xy: stations_visibility(
            space, camera, xy, instrument_z, prism_height, instrument_range
        ),
    )
    scored = np.isfinite(fractions)
    candidates, fractions = candidates[scored], fractions[scored]
    keys = _keys(candidates, fractions, centre)
    order = sorted(range(len(keys)), key=keys.__getitem__, reverse=True)
    first = order[0] if order else None
    best = (
        None
        if first is None
        else Station(camera_name, candidates[first], float(fractions[first]), centre)
    )
    if best is not None and best.visible >= need and gives_data is not None:
        tried = [k for k in order[:MOST_TRIED] if fractions[k] >= need]
        first = None
        for k in tried:
            grade = int(gives_data(candidates[k]))
            if grade >= REACHED:
                return Station(camera_name, candidates[k], float(fractions[k]), centre)
            if grade and first is None:
                first = k
        if first is not None:  # every one stands between the children and the stops
            return Station(camera_name, candidates[first], float(fractions[first]), centre)
        raise NoStationError(
            f"no station that sees {100 * need:.0f} % of camera {camera_name!r}'s floor view "
            "leaves a child a place in it that shows an LED to the camera and its prisms to "
            f"the total station ({len(tried)} tried, the best at {np.round(best.xy, 2).tolist()})"
        )
    if best is None or best.visible < need:
        found = (
            "no reachable place near it"
            if best is None
            else f"at best {100 * best.visible:.0f} % (from {np.round(best.xy, 2).tolist()})"
        )
        avoided = (
            ""
            if avoid is None or not len(avoid)
            else f" {AVOID_RADIUS:g} m or more from {np.round(avoid, 2).tolist()}"
        )
        raise NoStationError(
            f"no station{avoided} sees {100 * need:.0f} % of camera {camera_name!r}'s floor "
            f"view: {found}; is the camera placed and aimed as in the map's frame?",
            best,
        )
    return best


def _scored(
    candidates: NDArray[np.float64],
    centre: NDArray[np.float64],
    grid: float,
    visibility: Callable[[NDArray[np.float64]], NDArray[np.float64]],
) -> NDArray[np.float64]:
    """(K,) the visible fraction of the (K, 2) ``candidates`` (on the ``grid`` about
    ``centre``) worth scoring, NaN for the others: every other candidate of each row and
    column is scored first (a quarter of them), then the unscored neighbours of the
    :data:`REFINED` best (the fraction changes little over a grid step, and those scoring
    a lot cost most: every one of their lines of sight is tested against the walls)."""
    out = np.full(len(candidates), np.nan)
    if len(candidates) <= COARSE_FROM:
        out[:] = visibility(candidates)
        return out
    steps = np.rint((candidates - centre) / grid).astype(int)
    coarse = np.flatnonzero(np.all(steps % 2 == 0, axis=1))
    out[coarse] = visibility(candidates[coarse])
    keys = _keys(candidates[coarse], out[coarse], centre)
    best = coarse[sorted(range(len(coarse)), key=keys.__getitem__, reverse=True)[:REFINED]]
    near = np.abs(steps[:, None, :] - steps[None, best, :]).max(axis=2) <= 1  # (K, B)
    fine = np.flatnonzero(near.any(axis=1) & np.isnan(out))
    if len(fine):
        out[fine] = visibility(candidates[fine])
    return out


def _keys(
    candidates: NDArray[np.float64], fractions: NDArray[np.float64], centre: NDArray[np.float64]
) -> list[tuple[int, float]]:
    """Each candidate's rank key, higher better: its fraction in steps of
    :data:`SEES_EQUALLY`, then the nearness of its distance from ``centre`` to
    :data:`PREFERRED`."""
    return [
        (round(frac / SEES_EQUALLY), -abs(float(np.linalg.norm(xy - centre)) - PREFERRED))
        for xy, frac in zip(candidates, fractions.tolist(), strict=True)
    ]


ARRIVAL = 2.5
"""How far from the parent the children stand when it arrives at a station, m (the
formation's reach)."""

NEAR_STATION = 12.0
"""How far from a station :func:`stops_reached` follows the children's floor, m (the
farthest a station stands from its camera's view)."""

ARRIVAL_SHARE = 0.75
"""Share of the circle :data:`ARRIVAL` round a station the pieces of floor that hold its
data stops must hold (:func:`stops_reached`)."""

CHILD_KEEP = PARENT_BODY + CHILD_BODY + ROBOT_MARGIN
"""How far a child's centre keeps from the standing parent's, m (as its drives do)."""

STATION_SLACK = 0.1
"""How far the parent may stand from its planned station, m, as :func:`stops_reached`
allows for it (its CPS error on arrival, a few centimetres across the way after a few
legs): a passage beside the station narrower than this does not let the children pass."""


def stops_reached(
    child_free: BaseGeometry,
    station_xy: NDArray[np.float64],
    stops_xy: NDArray[np.float64],
    start_xy: NDArray[np.float64] | None = None,
) -> bool:
    """Whether the children, arriving with the parent, reach the data stops (N, 2)
    ``stops_xy`` (W, m) while it stands at ``station_xy``.

    ``child_free`` (W) is where a child's centre may be. Near the station and less
    :data:`CHILD_KEEP` round the parent (and :data:`STATION_SLACK`: the parent stands
    where it arrives, not on the plan's point), it falls into pieces where the parent
    stands in a passage (a corridor, a door's mouth); the children may arrive on any piece the
    circle :data:`ARRIVAL` round the parent crosses. The pieces that hold the stops must
    hold :data:`ARRIVAL_SHARE` of that circle: the parent must not stand between the
    floor the children come from and the view. True where no stop lies near it.

    Where the start is known (``start_xy``, W), the group comes from its side and the
    children stand ahead of the parent: :data:`ARRIVAL_SHARE` of the stops near it must
    lie on pieces away from the floor that joins the start (``child_free`` less the
    parent's circle), whatever their share of the circle."""
    station = Point(np.asarray(station_xy, dtype=float).reshape(2))
    near = child_free.intersection(station.buffer(NEAR_STATION))
    near = near.difference(station.buffer(CHILD_KEEP + STATION_SLACK))
    pieces = [g for g in getattr(near, "geoms", [near]) if g.area > 0]
    stops = np.asarray(stops_xy, dtype=float).reshape(-1, 2)
    if len(pieces) < 2 or not len(stops):
        return True
    ring = station.buffer(ARRIVAL).exterior
    arrive = np.array([g.intersection(ring).length for g in pieces])
    held = np.array([shapely.contains_xy(g, stops[:, 0], stops[:, 1]).any() for g in pieces])
    if not held.any():
        return True
    if start_xy is not None:
        home = _start_side(child_free, station, Point(np.asarray(start_xy, float).reshape(2)))
        if home is not None:
            inside = np.array([shapely.contains_xy(g, stops[:, 0], stops[:, 1]) for g in pieces])
            away = [not home.intersects(g.representative_point()) for g in pieces]
            return bool(inside[away].sum() >= ARRIVAL_SHARE * inside.sum())
    if arrive.sum() <= 0.0:
        return True
    return bool(arrive[held].sum() >= ARRIVAL_SHARE * arrive.sum())


def _start_side(child_free: BaseGeometry, station: Point, start: Point) -> BaseGeometry | None:
    """The piece of ``child_free`` less the parent's circle at ``station`` that holds
    ``start`` (the nearest where the circle covers it); None where the circle does not cut
    the floor into pieces."""
    rest = child_free.difference(station.buffer(CHILD_KEEP + STATION_SLACK))
    pieces = [g for g in getattr(rest, "geoms", [rest]) if g.area > 0]
    if len(pieces) < 2:
        return None
    return min(pieces, key=start.distance)


def _candidates(reachable: BaseGeometry, centre: NDArray, grid: float) -> NDArray[np.float64]:
    """(K, 2) grid points of ``reachable`` within the band around ``centre``."""
    xs = np.arange(centre[0] - FARTHEST, centre[0] + FARTHEST + grid / 2, grid)
    ys = np.arange(centre[1] - FARTHEST, centre[1] + FARTHEST + grid / 2, grid)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    d = np.linalg.norm(pts - centre, axis=1)
    pts = pts[(d >= NEAREST) & (d <= FARTHEST)]
    if len(pts) == 0:
        return pts
    return pts[shapely.contains_xy(reachable, pts[:, 0], pts[:, 1])]
