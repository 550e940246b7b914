"""Each camera's station for a site planned on a map (:mod:`twin.planning.site`): the place
that sees enough of the camera's floor view and from which the children reach its data
stops past the standing parent, coming from the start's side where the start is known.

The data stops are the campaign's own planner's (:func:`twin.campaign.plan.accurate_stops.
partial_view_stops`), found once for a (camera, place) and kept (:data:`StopsSeen`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from calib.camera import TsaiCamera
from twin.campaign.plan.accurate_stops import partial_view_stops
from twin.planning.boxes import BoxedSpace
from twin.planning.frames import MapPose
from twin.planning.site_start import camera_in_world
from twin.planning.stations import (
    REACHED,
    NoStationError,
    Station,
    choose_station,
    stops_reached,
)
from twin.scenario.loader import validate_model
from twin.scenario.map_space import map_obstacle
from twin.scenario.robots import INSTRUMENT_HEIGHT
from twin.scenario.schema import CameraConfig, MarkerConfig, Noise, Space
from twin.scenario.visibility import stations_visibility

STATION_NEED = 0.5
"""Least fraction of a camera's floor view a station must see (the scenario's default
``calibration.min_visible_fraction``)."""

STATION_FLOOR = 0.25
"""Least fraction a station may see where none sees :data:`STATION_NEED` (shelves or a
wall across the camera's view): a quarter of the view still holds the station's data set
spread over half the view's width and depth, which a calibration needs; the plan then
lowers the scenario's ``calibration.min_visible_fraction`` to what its stations see. A
camera no station sees this much of is left out of the plan, named."""

StopsSeen = dict[tuple[str, bytes], list[NDArray[np.float64]]]
"""The data stops' (2,) places found from a station, by camera name and the station's (2,)
place (its bytes), in one W: what the station search found, kept for the check of the
stations once the start is known."""


def data_stops(
    space: Space, camera: TsaiCamera, xy: NDArray[np.float64], floor_z: float
) -> list[NDArray[np.float64]]:
    """The (2,) places (m, W) of the data stops the campaign's planner finds for ``camera``
    from a station at ``xy`` ((2,) m; the instrument on the parent there, no anchor yet)."""
    ts = Noise().total_station
    found = partial_view_stops(
        space,
        MarkerConfig().assembly(),
        (ts.range_min, ts.range_max),
        camera,
        xy,
        floor_z + INSTRUMENT_HEIGHT,
        None,
    )
    return [s.stop.xy for s in found]


def site_stations(
    cameras: Sequence[Mapping[str, Any]],
    chosen: Sequence[str],
    pose: MapPose,
    boxed: BoxedSpace,
    station_free: tuple[BaseGeometry, BaseGeometry],
    child_free: BaseGeometry,
    floor_z: float,
    avoid: Mapping[str, Sequence[Sequence[float]]] | None = None,
    start: NDArray[np.float64] | None = None,
    seen: StopsSeen | None = None,
) -> tuple[dict[str, Station], dict[str, str]]:
    """Each chosen camera's station in the frame ``pose`` makes W: on the roomy floor
    (``station_free[0]``) where one there sees :data:`STATION_NEED`, else on the floor the
    parent can reach (``station_free[1]``), else the one that sees the most of the two
    where it sees :data:`STATION_FLOOR`; away from the camera's places in ``avoid`` (map
    frame; ``boxed``: the map's blocked floor in that W); one from which the children
    reach the data stops past the standing parent (:func:`stops_reached` on
    ``child_free``, map frame, where a child's centre may be; from the side of ``start``,
    the parent's start in that W, where it is known). ``seen``: the data stops found from
    each (camera, place) in this W, read and added to (default: none kept). Returns the
    stations by camera name, and the cameras with none, each with why (the best fraction
    found and where)."""
    space = map_space(boxed, floor_z)
    by_name = {str(c["name"]): c for c in cameras}
    marker = MarkerConfig()
    ts = Noise().total_station
    wheres = [pose.geometry2world(g) for g in station_free if not g.is_empty]
    child_w = pose.geometry2world(child_free)
    out: dict[str, Station] = {}
    hidden: dict[str, str] = {}
    for name in chosen:
        camera = validate_model(CameraConfig, camera_in_world(by_name[name], pose, floor_z)).tsai()
        found: list[Station] = []
        best: Station | None = None
        why = "no place the robots reach near its floor view"

        def gives_data(
            xy: NDArray[np.float64], camera: TsaiCamera = camera, name: str = name
        ) -> int:
            # The campaign's own planner of data stops, from the station (no anchor yet),
            # and whether the children reach them past the standing parent.
            key = (name, xy.tobytes())
            stops = None if seen is None else seen.get(key)
            if stops is None:
                stops = data_stops(space, camera, xy, floor_z)
                if seen is not None:
                    seen[key] = stops
            if not stops:
                return 0
            reached = stops_reached(child_w, xy, stops, start)
            return REACHED if reached else 1

        # The roomy floor first, then all the parent reaches; where no station sees
        # STATION_NEED, the best of those that see STATION_FLOOR.
        for need in (STATION_NEED, STATION_FLOOR):
            for where in wheres:
                try:
                    found.append(
                        choose_station(
                            name,
                            camera,
                            space,
                            where,
                            instrument_z=floor_z + INSTRUMENT_HEIGHT,
                            prism_height=float(np.mean([c[2] for c in marker.cubes])),
                            instrument_range=(ts.range_min, ts.range_max),
                            need=need,
                            avoid=_avoided(avoid, name, pose),
                            gives_data=gives_data,
                        )
                    )
                    if need == STATION_NEED:
                        break
                except NoStationError as exc:
                    if exc.best is None:
                        why = str(exc)
                    elif best is None or exc.best.visible > best.visible:
                        best = exc.best
            if found:
                break
        if found:
            out[name] = max(found, key=lambda st: st.visible)
        elif best is None:
            hidden[name] = why
        else:
            x, y = pose.world2map(best.xy)
            hidden[name] = (
                f"no station sees {100 * STATION_FLOOR:.0f} % of its floor view (walls or "
                f"obstacles hide it): at best {100 * best.visible:.0f} % from ({x:.2f}, "
                f"{y:.2f}); is the camera placed and aimed as in the map's frame?"
            )
    return out, hidden


def gives_data_from(
    cameras: Sequence[Mapping[str, Any]],
    name: str,
    station: NDArray[np.float64],
    boxed: BoxedSpace,
    child_free: BaseGeometry,
    floor_z: float,
    start: NDArray[np.float64],
    seen: StopsSeen | None = None,
) -> bool:
    """Whether the children, coming with the parent from ``start``, reach camera ``name``'s
    data stops from ``station`` (:func:`stops_reached`; all in the map's frame); the stops
    as ``seen`` holds them where the station search found them there."""
    stops = None if seen is None else seen.get((name, station.tobytes()))
    if stops is not None:
        return not stops or stops_reached(child_free, station, stops, start)
    by_name = {str(c["name"]): c for c in cameras}
    camera = validate_model(CameraConfig, camera_in_world(by_name[name], MapPose(), floor_z)).tsai()
    stops = data_stops(map_space(boxed, floor_z), camera, station, floor_z)
    return not stops or stops_reached(child_free, station, stops, start)


def visible_from(
    boxed: BoxedSpace, camera: Mapping[str, Any], xy: NDArray[np.float64], floor_z: float
) -> float:
    """The fraction of ``camera``'s floor view (a cameras file's entry in the W of
    ``boxed``) the total station sees from a station at (2,) ``xy`` (m, W), as the
    scenario's check of a visit computes it: the instrument's range and the prisms' mean
    height of the defaults."""
    ts = Noise().total_station
    tsai = validate_model(CameraConfig, camera).tsai()
    prism = float(np.mean([c[2] for c in MarkerConfig().cubes]))
    return float(
        stations_visibility(
            map_space(boxed, floor_z),
            tsai,
            np.asarray(xy, dtype=float).reshape(1, 2),
            floor_z + INSTRUMENT_HEIGHT,
            prism,
            (ts.range_min, ts.range_max),
        )[0]
    )


def _avoided(
    avoid: Mapping[str, Sequence[Sequence[float]]] | None, name: str, pose: MapPose
) -> NDArray[np.float64] | None:
    """(K, 2) the places camera ``name``'s station avoids, in the W of ``pose``; None if
    none."""
    places = (avoid or {}).get(name)
    if not places:
        return None
    return pose.map2world(np.asarray(places, dtype=float).reshape(-1, 2))


def map_space(space: BoxedSpace, floor_z: float) -> Space:
    """The scenario's space with the map's boxes, for the planner's own checks."""
    room = validate_model(
        Space, {"size": list(space.size), "origin": list(space.origin), "floor_z": floor_z}
    )
    return room.with_map_boxes(tuple(map_obstacle(k, b) for k, b in enumerate(space.boxes)))
