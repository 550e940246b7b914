"""A generated hospital floor: corridors joined end to end, alcoves off them, and cameras
along both, as a ROS occupancy grid and a cameras file (the inputs of ``twin site``).

The floor scales with the number of cameras, about 22 m of corridor a camera: ``rows``
corridors 4 m wide, 12 m apart (the rooms between them are blocked), joined at alternate
ends by 10 m lobbies so that the corridors make one serpentine. Two cameras in three hang
on a corridor wall 2.5 m up and look along the corridor, 25 degrees down; every third
looks into an alcove (8 m wide, 5 m deep) that opens off the corridor.

Run ``python -m twin.planning.sample_floor DIR [--cameras N]`` to write ``DIR/map.png``,
``DIR/map.yaml`` and ``DIR/cameras.yaml``; ``scenarios/hospital_floor/`` was made so.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

RESOLUTION = 0.05
"""Cell size of the map, m (a SLAM map's usual 5 cm)."""

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
        corridor_length: length of each corridor, m. rows: number of corridors.
    """

    free: np.ndarray
    origin: tuple[float, float]
    cameras: list[dict[str, Any]]
    corridor_length: float
    rows: int


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
    return SampleFloor(free, (0.0, 0.0), out, length, rows)


def write_floor(folder: str | Path, cameras: int = 30) -> tuple[Path, Path]:
    """Write ``map.png``, ``map.yaml`` and ``cameras.yaml`` into ``folder``; returns the
    map's YAML and the cameras file."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    floor = hospital_floor(cameras)
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
    header = (
        f"# {cameras} cameras of a generated hospital floor (twin.planning.sample_floor), in\n"
        "# the map's frame; position z is the height above the floor, m.\n"
    )
    (folder / "cameras.yaml").write_text(
        header + yaml.safe_dump(floor.cameras, sort_keys=False, default_flow_style=None)
    )
    return folder / "map.yaml", folder / "cameras.yaml"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--cameras", type=int, default=30)
    args = parser.parse_args(argv)
    grid, cams = write_floor(args.folder, args.cameras)
    print(f"wrote {grid} and {cams}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
