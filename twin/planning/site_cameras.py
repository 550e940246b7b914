"""The cameras of a site: read from the cameras file (the map's frame), and checked against
the boxes the map's blocked floor is laid as.

A camera is usually mounted on a wall, at its face. The grid the boxes lie on puts a box's
edge up to half a cell past the map's wall, so such a camera can stand just inside a box:
it is moved off the box by the least distance (:func:`clear_cameras`, which says so by
name). A camera deeper inside blocked floor is refused, named in the map's frame.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from shapely.geometry import Point

from calib.io.text import read_text, yaml_load
from twin.planning.boxes import BoxedSpace
from twin.planning.floor_map import FloorMap, MapError
from twin.planning.frames import MapPose
from twin.scenario.errors import ScenarioError
from twin.scenario.loader import validate_model
from twin.scenario.schema import CameraConfig

__all__ = ["CAMERA_KEYS", "WALL_GAP", "clear_cameras", "read_cameras"]

WALL_GAP = 0.01
"""How far from a box's face a camera moved off it is put, m."""

ON_FACE = 1e-9
"""A camera this near a box's face is on it, m (the scenario's own check, which holds a
face to belong to its box, rounds a face placed in W differently)."""

CAMERA_KEYS = (
    "name",
    "position",
    "view_direction",
    "f",
    "cx",
    "cy",
    "kappa1",
    "sx",
    "image_size",
    "opencv_distortion",
    "sensor",
    "led_centroid_px",
)


def read_cameras(path: str | Path) -> list[dict[str, Any]]:
    """The cameras file: a YAML list (or mapping with ``cameras``), or TOML
    ``[[cameras]]``, each with a scenario camera's keys, in the map's frame (``position``'s
    z is the height above the floor, m).

    Raises:
        MapError: the file cannot be read, or a camera is not a table of known keys, or
            one of its values is not a scenario camera's (a NaN focal length, say); the
            message names the camera (its index and name) and the key.
    """
    path = Path(path)
    try:
        text = read_text(path)
        raw: Any = tomllib.loads(text) if path.suffix == ".toml" else yaml_load(text)
    except (OSError, ValueError, yaml.YAMLError) as exc:
        raise MapError(path, f"cannot read the cameras: {exc}") from None
    if isinstance(raw, Mapping):
        raw = raw.get("cameras")
    if not isinstance(raw, list) or not raw:
        raise MapError(path, "expected a list of cameras (YAML list, or TOML [[cameras]])")
    out = []
    for k, cam in enumerate(raw):
        where = f"camera {k}" + (f" ({cam.get('name')!r})" if isinstance(cam, Mapping) else "")
        if not isinstance(cam, Mapping):
            raise MapError(path, f"{where}: expected a table of camera keys, got {cam!r}")
        unknown = sorted(set(cam) - set(CAMERA_KEYS))
        if unknown:
            raise MapError(path, f"{where}: unknown keys {unknown}; expected {CAMERA_KEYS}")
        for key in ("name", "position", "view_direction", "f", "cx", "cy", "image_size"):
            if key not in cam:
                raise MapError(path, f"{where}: the key {key!r} is missing")
        position = cam["position"]
        if not (
            isinstance(position, list)
            and len(position) == 3
            and all(_finite_number(v) for v in position)
        ):
            raise MapError(
                path,
                f"{where}: position: expected 3 finite numbers (x, y in the map's frame and "
                f"the height above the floor, m), got {position!r}",
            )
        try:
            # The position is the map's (any size: the map's own coordinates); the rest is
            # checked as a scenario camera's.
            validate_model(CameraConfig, {**cam, "position": [0.0, 0.0, position[2]]}, path)
        except ScenarioError as exc:
            problems = "; ".join(str(issue) for issue in exc.issues)
            raise MapError(path, f"{where}: {problems}") from None
        out.append(dict(cam))
    return out


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def clear_cameras(
    floor: FloorMap,
    cameras: Sequence[Mapping[str, Any]],
    pose: MapPose,
    boxed: BoxedSpace,
    floor_z: float,
) -> tuple[list[Mapping[str, Any]], dict[str, str]]:
    """The cameras, those inside a box below its top by no more than a grid cell moved off
    it by the least distance (to :data:`WALL_GAP` past its face: see the module).

    Args:
        floor: the map. cameras: the cameras file's entries, map frame.
        pose: W in the map. boxed: the map's blocked floor as boxes in W.
        floor_z: the floor's height in W, m.

    Returns:
        The cameras (a moved one with its new ``position``, map frame), and by name each
        moved camera: from where to where it moved and by how much (map frame).

    Raises:
        MapError: a camera deeper inside a box, naming it and what of the map it stands
            in (its extent and height), map frame.
    """
    if not boxed.boxes:
        return list(cameras), {}
    centres = np.array([b.center for b in boxed.boxes])
    halves = 0.5 * np.array([b.size for b in boxed.boxes])
    tops = np.array([floor_z + b.height for b in boxed.boxes])
    lo, hi = centres - halves, centres + halves
    room = (np.asarray(boxed.origin), np.asarray(boxed.origin) + np.asarray(boxed.size[:2]))
    out: list[Mapping[str, Any]] = []
    moved: dict[str, str] = {}
    for cam in cameras:
        p = np.asarray(cam["position"], dtype=float)
        xy = pose.map2world(p[:2])
        high = (floor_z + p[2]) < tops
        if not _holding(xy, lo, hi, high).size:
            out.append(cam)
            continue
        to = _way_out(xy, lo[high], hi[high], room, boxed.resolution)
        if to is None:
            _refuse(floor, cam, pose, boxed, int(_holding(xy, lo, hi, high)[0]))
        mx, my = (float(v) for v in pose.world2map(to))
        out.append({**cam, "position": [mx, my, float(p[2])]})
        moved[str(cam["name"])] = (
            f"at ({p[0]:.2f}, {p[1]:.2f}) it stood inside the blocked floor as the boxes' "
            f"{boxed.resolution:g} m grid lays it (a camera on a wall's face); moved "
            f"{float(np.linalg.norm(to - xy)):.3f} m off it, to ({mx:.3f}, {my:.3f}) "
            "(the map's frame, m)"
        )
    return out, moved


def _holding(
    xy: NDArray[np.float64], lo: NDArray, hi: NDArray, high: NDArray[np.bool_]
) -> NDArray[np.intp]:
    """Indices of the boxes ((B, 2) corners ``lo``, ``hi``, W) whose footprint holds (2,)
    ``xy`` (its boundary included, to :data:`ON_FACE`) where ``high`` (B,) (their top
    above the camera)."""
    inside = (lo - ON_FACE <= xy) & (xy <= hi + ON_FACE)
    return np.flatnonzero(high & np.all(inside, axis=1))


def _way_out(
    xy: NDArray[np.float64],
    lo: NDArray,
    hi: NDArray,
    room: tuple[NDArray, NDArray],
    most: float,
) -> NDArray[np.float64] | None:
    """The nearest place to (2,) ``xy`` within ``most`` (m) of it, inside the ``room``
    (its corners, W) and outside every box (corners ``lo``, ``hi``: those above the
    camera), by steps across the boxes' faces (to :data:`WALL_GAP` past them: two steps
    leave the corner where two boxes meet); None if none is."""
    every = np.ones(len(lo), dtype=bool)
    frontier, free = [xy], []
    for _ in range(3):
        step = []
        for q in frontier:
            holders = _holding(q, lo, hi, every)
            if not holders.size:
                free.append(q)
                continue
            for k in holders:
                for axis in (0, 1):
                    for edge in (lo[k, axis] - WALL_GAP, hi[k, axis] + WALL_GAP):
                        r = q.copy()
                        r[axis] = edge
                        if np.linalg.norm(r - xy) <= most:
                            step.append(r)
        frontier = step
    free += [q for q in frontier if not _holding(q, lo, hi, every).size]
    free = [q for q in free if np.all(room[0] < q) and np.all(q < room[1])]
    if not free:
        return None
    return min(free, key=lambda q: float(np.linalg.norm(q - xy)))


def _refuse(
    floor: FloorMap, cam: Mapping[str, Any], pose: MapPose, boxed: BoxedSpace, box: int
) -> None:
    """Refuse a camera inside ``boxed.boxes[box]`` (below its top), in the terms of the
    cameras file: the camera's name, where it stands in the map's frame and what of the
    map it stands in.

    Raises:
        MapError: always, naming the camera and the obstacle, map frame.
    """
    p = np.asarray(cam["position"], dtype=float)
    mapped = [ob for ob in floor.obstacles if ob.footprint.covers(Point(p[:2]))]
    if mapped:
        ob = mapped[0]
        x0, y0, x1, y1 = ob.footprint.bounds
        high = "up to the ceiling" if math.isinf(ob.height) else f"{ob.height:.2f} m high"
        what = f"the map's obstacle {ob.name!r}"
    else:  # a wall or floor the map does not show free, as its box laid on the grid
        found = boxed.boxes[box]
        half = 0.5 * np.asarray(found.size)
        square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
        corners = pose.world2map(np.asarray(found.center) + half * square)
        (x0, y0), (x1, y1) = corners.min(axis=0), corners.max(axis=0)
        high = f"{found.height:.2f} m high"
        what = "the map's blocked floor"
    raise MapError(
        floor.source,
        f"camera {cam['name']!r} at ({p[0]:.2f}, {p[1]:.2f}), {p[2]:.2f} m above the "
        f"floor, stands inside {what} (x {x0:.2f} to {x1:.2f}, y {y0:.2f} to {y1:.2f}, "
        f"{high}; the map's frame, m), more than a grid cell ({boxed.resolution:g} m) from "
        "its face; expected a camera over free floor, above what stands there, or on a "
        "wall's face",
    )
