"""Generated floors as a ROS occupancy grid and a cameras file (the inputs of ``twin
site``): a hospital floor (corridors joined end to end, alcoves off them, cameras along
both) and an office floor (:func:`office_floor`: a grid of corridors, rooms with doors).

The hospital floor scales with the number of cameras, about 22 m of corridor a camera: ``rows``
corridors 4 m wide, 12 m apart (the rooms between them are blocked), joined at alternate
ends by 10 m lobbies so that the corridors make one serpentine. Two cameras in three hang
on a corridor wall 2.5 m up and look along the corridor, 25 degrees down; every third
looks into an alcove (8 m wide, 5 m deep) that opens off the corridor.

Run ``python -m twin.planning.sample_floor DIR [--cameras N] [--office W H [--seed S]]``
to write ``DIR/map.png``, ``DIR/map.yaml`` and ``DIR/cameras.yaml``;
``scenarios/hospital_floor/`` was made so.
"""

from __future__ import annotations

import argparse
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

RESOLUTION = 0.05
"""Cell size of the map, m (a SLAM map's usual 5 cm)."""

_log = logging.getLogger(__name__)

CORRIDOR = 4.0
"""Corridor width, m (a hospital's main corridor, where beds pass)."""

JOIN = 10.0
"""Width of the lobby that joins two corridors at the serpentine's turns, m: the total
station must see the children around a corner, which a corridor-wide join does not
allow (the corners hide them)."""

PITCH = 12.0
"""Distance between the corridors' centre lines, m (9 m of rooms between two)."""

ALCOVE = (8.0, 5.0)
"""An alcove's width along the corridor and depth, m."""

CAMERA_HEIGHT = 2.5
"""The cameras' height above the floor, m."""

MARGIN = 2.0
"""Blocked border around the floor, m."""


@dataclass(frozen=True)
class SampleFloor:
    """A generated floor.

    Attributes:
        free: (H, W) bool, free cells (row 0 is the map's top).
        origin: (x, y) of the grid's lower-left corner, m.
        cameras: the cameras file's entries (map frame, z above the floor).
    """

    free: np.ndarray
    origin: tuple[float, float]
    cameras: list[dict[str, Any]]


def hospital_floor(cameras: int = 30, metres_per_camera: float = 22.0) -> SampleFloor:
    """The floor for ``cameras`` cameras (see the module)."""
    if cameras < 2:
        raise ValueError(f"a floor needs at least 2 cameras, got {cameras}")
    rows = max(2, round(math.sqrt(cameras / 2)))
    per_row = math.ceil(cameras / rows)
    length = max(30.0, metres_per_camera * cameras / rows)
    width = length + 2 * MARGIN
    height = (rows - 1) * PITCH + CORRIDOR + 2 * MARGIN + ALCOVE[1]
    nx, ny = math.ceil(width / RESOLUTION), math.ceil(height / RESOLUTION)
    free = np.zeros((ny, nx), dtype=bool)

    def open_rect(x0: float, y0: float, x1: float, y1: float) -> None:
        c0, c1 = round(x0 / RESOLUTION), round(x1 / RESOLUTION)
        r0, r1 = ny - round(y1 / RESOLUTION), ny - round(y0 / RESOLUTION)
        free[max(r0, 0) : r1, max(c0, 0) : c1] = True

    centres = [MARGIN + CORRIDOR / 2 + k * PITCH for k in range(rows)]
    x0, x1 = MARGIN, MARGIN + length
    for y in centres:
        open_rect(x0, y - CORRIDOR / 2, x1, y + CORRIDOR / 2)
    for k in range(rows - 1):  # the joins, at alternate ends: one serpentine
        xj = x1 - JOIN if k % 2 == 0 else x0
        open_rect(xj, centres[k] - CORRIDOR / 2, xj + JOIN, centres[k + 1] + CORRIDOR / 2)
    out: list[dict[str, Any]] = []
    spacing = length / per_row
    for k in range(cameras):
        row, slot = divmod(k, per_row)
        y = centres[row]
        x = x0 + (slot + 0.5) * spacing
        # Looking along the corridor, away from its west end: the end lobbies are turns
        # of the route, and a station stands 2-12 m from its camera's view.
        heading = 1.0
        if k % 3 == 2:
            # An alcove on the corridor's upper side, a camera on its back wall.
            side = 1.0
            y_edge = y + side * CORRIDOR / 2
            y_back = y_edge + side * ALCOVE[1]
            open_rect(
                x - ALCOVE[0] / 2, min(y_edge, y_back), x + ALCOVE[0] / 2, max(y_edge, y_back)
            )
            position = [x, y_back - side * 0.3, CAMERA_HEIGHT]
            direction = [0.0, -side, -0.55]
        else:
            position = [x - heading * 3.0, y + CORRIDOR / 2 - 0.3, CAMERA_HEIGHT]
            direction = [heading, -0.12, -math.tan(math.radians(25.0))]
        out.append(
            {
                "name": f"cam{k + 1}",
                "position": [round(v, 3) for v in position],
                "view_direction": [round(v, 4) for v in direction],
                "f": 300.0,
                "cx": 159.5,
                "cy": 119.5,
                "image_size": [320, 240],
            }
        )
    return SampleFloor(free, (0.0, 0.0), out)


OFFICE_CORRIDOR = 4.0
"""An office floor's corridor width, m."""

OFFICE_PITCH = 18.0
"""Target distance between an office floor's parallel corridors, m."""

OFFICE_WALL = 0.2
"""Thickness of the walls between an office's rooms and corridors, m."""

OFFICE_ROOM = 8.0
"""Target size of an office room along each axis, m (a block between two corridors holds
two rooms across where it is at least 1.5 times this)."""

OFFICE_DOOR = 4.0
"""Width of an office room's door, m."""

OFFICE_MARGIN = 1.0
"""Blocked border (the outer wall) of an office floor, m."""

OFFICE_CAMERA_HEIGHT = 2.9
"""An office camera's height above the floor, m (below the 3 m ceiling a ROS map gets)."""

OFFICE_TILT_DEG = 30.0
"""How far an office camera looks down, degrees."""


def office_floor(
    width: float = 60.0,
    height: float = 60.0,
    cameras: int = 30,
    seed: int = 0,
    rough: float = 0.0,
) -> SampleFloor:
    """A generated office floor of ``width`` x ``height`` m with ``cameras`` cameras.

    Corridors :data:`OFFICE_CORRIDOR` wide cross the floor along x and along y, about
    :data:`OFFICE_PITCH` apart, from outer wall to outer wall; the blocks between them are
    rooms (one or two across each way, walls :data:`OFFICE_WALL` thick), each with one
    door :data:`OFFICE_DOOR` wide onto a corridor, its side and place drawn from ``seed``.
    The cameras hang :data:`OFFICE_CAMERA_HEIGHT` up and look :data:`OFFICE_TILT_DEG` down:
    a corridor camera at one end of a stretch between two crossings, beside a wall, looking
    along it; a room camera at the middle of the wall opposite its door, looking at the
    door. Corridor and room cameras alternate, each kind in an order drawn from ``seed``.
    With ``rough`` > 0 each free cell beside a wall is blocked with that probability (the
    ragged walls of a SLAM map, and a floor of thousands of boxes).

    Raises:
        ValueError: fewer than 2 cameras, a floor under 20 m a side, or more cameras than
            the floor has places for.
    """
    if cameras < 2:
        raise ValueError(f"a floor needs at least 2 cameras, got {cameras}")
    if min(width, height) < 20.0:
        raise ValueError(f"an office floor is at least 20 x 20 m, got {width} x {height}")
    rng = np.random.default_rng(seed)
    nx, ny = math.ceil(width / RESOLUTION), math.ceil(height / RESOLUTION)
    free = np.zeros((ny, nx), dtype=bool)

    def open_rect(x0: float, y0: float, x1: float, y1: float) -> None:
        c0, c1 = round(x0 / RESOLUTION), round(x1 / RESOLUTION)
        r0, r1 = ny - round(y1 / RESOLUTION), ny - round(y0 / RESOLUTION)
        free[max(r0, 0) : r1, max(c0, 0) : c1] = True

    m, half = OFFICE_MARGIN, OFFICE_CORRIDOR / 2
    spans = (width, height)
    centres = []  # per axis: the centres of the corridors that cross that axis
    for span in spans:
        n = max(1, round((span - 2 * m) / OFFICE_PITCH))
        step = (span - 2 * m) / n
        centres.append([m + (k + 0.5) * step for k in range(n)])
    for c in centres[0]:  # corridors along y
        open_rect(c - half, m, c + half, height - m)
    for c in centres[1]:  # corridors along x
        open_rect(m, c - half, width - m, c + half)
    # Each axis's room intervals (lo, hi, corridor below, corridor above).
    pieces: list[list[tuple[float, float, bool, bool]]] = []
    for span, cs in zip(spans, centres, strict=True):
        edges = [m, *[v for c in cs for v in (c - half - OFFICE_WALL, c + half + OFFICE_WALL)]]
        edges.append(span - m)
        axis: list[tuple[float, float, bool, bool]] = []
        for k in range(0, len(edges), 2):
            lo, hi = edges[k], edges[k + 1]
            below, above = k > 0, k + 2 < len(edges)
            if below and above and hi - lo >= 1.5 * OFFICE_ROOM:
                mid = 0.5 * (lo + hi)
                axis += [
                    (lo, mid - OFFICE_WALL / 2, True, False),
                    (mid + OFFICE_WALL / 2, hi, False, True),
                ]
            else:
                axis.append((lo, hi, below, above))
        pieces.append(axis)
    corridor_cams = _corridor_cameras(centres, spans)
    room_cams = []
    for x0, x1, xlo, xhi in pieces[0]:
        for y0, y1, ylo, yhi in pieces[1]:
            open_rect(x0, y0, x1, y1)
            sides = [(0, -1.0)] * xlo + [(0, 1.0)] * xhi + [(1, -1.0)] * ylo + [(1, 1.0)] * yhi
            axis, sign = sides[int(rng.integers(len(sides)))]
            lo, hi = ((y0, y1), (x0, x1))[axis]
            slack = max(0.0, hi - lo - OFFICE_DOOR - 1.0)
            at = lo + 0.5 + OFFICE_DOOR / 2 + float(rng.uniform(0.0, slack))
            if not slack:
                at = 0.5 * (lo + hi)
            wall = (x0, x1, y0, y1)[2 * axis + (sign > 0)]
            outer = wall + sign * OFFICE_WALL
            a, b = min(wall, outer), max(wall, outer)
            if axis == 0:
                open_rect(a, at - OFFICE_DOOR / 2, b, at + OFFICE_DOOR / 2)
            else:
                open_rect(at - OFFICE_DOOR / 2, a, at + OFFICE_DOOR / 2, b)
            # The camera on the opposite wall's middle, looking at the door.
            centre = [0.5 * (x0 + x1), 0.5 * (y0 + y1)]
            back = (x0, x1, y0, y1)[2 * axis + (sign < 0)]
            position = list(centre)
            position[axis] = back + sign * 0.3
            look = [0.0, 0.0]
            look[axis] = sign
            room_cams.append((position, look))
    order = [
        [corridor_cams[k] for k in rng.permutation(len(corridor_cams))],
        [room_cams[k] for k in rng.permutation(len(room_cams))],
    ]
    if cameras > len(corridor_cams) + len(room_cams):
        raise ValueError(
            f"a {width:g} x {height:g} m office floor has places for "
            f"{len(corridor_cams) + len(room_cams)} cameras, {cameras} asked"
        )
    out: list[dict[str, Any]] = []
    down = -math.tan(math.radians(OFFICE_TILT_DEG))
    for k in range(cameras):
        kind = order[k % 2] or order[(k + 1) % 2]
        (x, y), (dx, dy) = kind.pop()
        out.append(
            {
                "name": f"cam{k + 1}",
                "position": [round(x, 3), round(y, 3), OFFICE_CAMERA_HEIGHT],
                "view_direction": [round(dx, 4), round(dy, 4), round(down, 4)],
                "f": 300.0,
                "cx": 159.5,
                "cy": 119.5,
                "image_size": [320, 240],
            }
        )
    if rough > 0.0:
        wall = np.zeros_like(free)
        wall[1:] |= ~free[:-1]
        wall[:-1] |= ~free[1:]
        wall[:, 1:] |= ~free[:, :-1]
        wall[:, :-1] |= ~free[:, 1:]
        free &= ~(wall & (rng.random(free.shape) < rough))
    return SampleFloor(free, (0.0, 0.0), out)


def _corridor_cameras(
    centres: list[list[float]], spans: tuple[float, float]
) -> list[tuple[list[float], list[float]]]:
    """(position (x, y), look (dx, dy)) of a camera at the start of each corridor stretch
    at least 6 m long between two crossings (or a crossing and the outer wall), beside the
    stretch's wall (alternate sides), looking along it."""
    half = OFFICE_CORRIDOR / 2
    out = []
    for axis in (0, 1):  # a corridor along y crosses the x axis at its centre
        along = 1 - axis
        bounds = [OFFICE_MARGIN]
        for c in centres[along]:
            bounds += [c - half, c + half]
        bounds.append(spans[along] - OFFICE_MARGIN)
        for k, c in enumerate(centres[axis]):
            for j in range(0, len(bounds), 2):
                lo, hi = bounds[j], bounds[j + 1]
                if hi - lo < 6.0:
                    continue
                side = 1.0 if (j // 2 + k) % 2 == 0 else -1.0
                position = [0.0, 0.0]
                position[axis] = c + side * (half - 0.3)
                position[along] = lo + 0.3
                look = [0.0, 0.0]
                look[along] = 1.0
                look[axis] = -0.1 * side
                out.append((position, look))
    return out


def write_floor(folder: str | Path, cameras: int = 30) -> tuple[Path, Path]:
    """Write ``map.png``, ``map.yaml`` and ``cameras.yaml`` into ``folder``; returns the
    map's YAML and the cameras file."""
    header = (
        f"# {cameras} cameras of a generated hospital floor (twin.planning.sample_floor), in\n"
        "# the map's frame; position z is the height above the floor, m.\n"
    )
    return _write(folder, hospital_floor(cameras), header)


def write_office_floor(
    folder: str | Path,
    width: float = 60.0,
    height: float = 60.0,
    cameras: int = 30,
    seed: int = 0,
    rough: float = 0.0,
) -> tuple[Path, Path]:
    """Write :func:`office_floor`'s ``map.png``, ``map.yaml`` and ``cameras.yaml`` into
    ``folder``; returns the map's YAML and the cameras file."""
    header = (
        f"# {cameras} cameras of a generated {width:g} x {height:g} m office floor (seed "
        f"{seed}, twin.planning.sample_floor),\n"
        "# in the map's frame; position z is the height above the floor, m.\n"
    )
    return _write(folder, office_floor(width, height, cameras, seed, rough), header)


def _write(folder: str | Path, floor: SampleFloor, header: str) -> tuple[Path, Path]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / "map.png"), np.where(floor.free, 254, 0).astype(np.uint8))
    meta = {
        "image": "map.png",
        "resolution": RESOLUTION,
        "origin": [floor.origin[0], floor.origin[1], 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    (folder / "cameras.yaml").write_text(
        header + yaml.safe_dump(floor.cameras, sort_keys=False, default_flow_style=None)
    )
    return folder / "map.yaml", folder / "cameras.yaml"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--cameras", type=int, default=30)
    parser.add_argument(
        "--office",
        type=float,
        nargs=2,
        metavar=("WIDTH", "HEIGHT"),
        help="an office floor of this size, m (default: the hospital floor)",
    )
    parser.add_argument("--seed", type=int, default=0, help="the office floor's seed")
    parser.add_argument(
        "--rough", type=float, default=0.0, help="the office walls' raggedness (0 to 1)"
    )
    args = parser.parse_args(argv)
    if args.office:
        width, height = args.office
        grid, cams = write_office_floor(
            args.folder, width, height, args.cameras, args.seed, args.rough
        )
    else:
        grid, cams = write_floor(args.folder, args.cameras)
    _log.info("wrote %s and %s", grid, cams)
    return 0


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    raise SystemExit(main())
