"""What a map-backed space costs: boxes, loading, MuJoCo's compile and render.

For each floor the table gives the boxes its blocked floor is laid as (0.1 m grid), the
time to read the map, to plan the site (``twin site`` without its run), to lay the
boxes, to load the planned scenario (map read again,
hash checked, boxes laid, cross-checks), to compile the MuJoCo world and to render one
camera frame (the median of 5, after one to warm up), and the scenario file's size.

Floors: the generated hospital floors (:mod:`twin.planning.sample_floor`) of 10 and 30
cameras, and a generated 60 x 60 m floor at 5 cm (:func:`square_floor`: rooms off three
corridors, pillars, a round atrium, SLAM-like rough walls and clutter) with two cameras,
started in the atrium.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/bench_map_space.py``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import yaml
from rich.console import Console
from rich.table import Table

RESOLUTION = 0.05
"""Cell of the generated square floor's map, m."""


def square_floor(folder: Path, side: float = 60.0) -> tuple[Path, Path]:
    """A ``side`` x ``side`` m floor as a ROS map at 5 cm, and two cameras over it: three
    corridors 3 m wide along x joined at both ends by two along y, rooms 5 m deep on both
    sides of each with 1 m doors, a 0.4 m pillar every 6 m by a corridor's walls, and a
    round atrium 16 m across in the middle; rough walls and clutter as a SLAM map shows.
    Returns the map's YAML and the cameras file."""
    folder.mkdir(parents=True, exist_ok=True)
    n = round(side / RESOLUTION)
    img = np.zeros((n, n), np.uint8)  # blocked

    def px(x: float, y: float) -> tuple[int, int]:
        return round(x / RESOLUTION), n - 1 - round(y / RESOLUTION)

    def rect(x0: float, y0: float, x1: float, y1: float, value: int) -> None:
        (c0, r1), (c1, r0) = px(x0, y0), px(x1, y1)
        img[max(r0, 0) : r1 + 1, max(c0, 0) : c1 + 1] = value

    wall = 0.2
    rect(1.0, 8.5, 4.0, side - 8.5, 254)  # the corridors at both ends, along y
    rect(side - 4.0, 8.5, side - 1.0, side - 8.5, 254)
    for k in range(3):
        yc = 10.0 + 20.0 * k
        rect(1.0, yc - 1.5, side - 1.0, yc + 1.5, 254)  # a corridor along x
        for x in np.arange(5.0, side - 9.0, 5.0):  # rooms on both sides, 1 m doors
            rect(x + wall, yc + 1.5 + wall, x + 5.0 - wall, yc + 6.5, 254)
            rect(x + 2.0, yc + 1.5, x + 3.0, yc + 1.5 + wall, 254)
            rect(x + wall, yc - 6.5, x + 5.0 - wall, yc - 1.5 - wall, 254)
            rect(x + 2.0, yc - 1.5 - wall, x + 3.0, yc - 1.5, 254)
        for j, x in enumerate(np.arange(7.0, side - 5.0, 6.0)):  # pillars by the walls
            y = yc + 1.3 if j % 2 else yc - 1.3
            rect(x - 0.2, y - 0.2, x + 0.2, y + 0.2, 0)
    centre = px(side / 2, side / 2)
    cv2.circle(img, centre, round(8.0 / RESOLUTION), 254, -1)
    # What a SLAM map shows besides: walls rough with furniture and scan noise (bumps up
    # to 15 cm off every wall), clutter in the rooms (chairs, bins: blobs up to 15 cm).
    rng = np.random.default_rng(0)
    free = img == 254
    edge = free & ~cv2.erode(free.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    rows, cols = np.nonzero(edge)
    for k in rng.choice(rows.size, size=rows.size // 40, replace=False):
        cv2.circle(img, (int(cols[k]), int(rows[k])), int(rng.integers(1, 4)), 0, -1)
    for _ in range(int(0.5 * side * side)):
        c, r = (int(v) for v in rng.integers(0, n, size=2))
        y = (n - 1 - r) * RESOLUTION
        in_corridor = min(abs(y - 10.0 - 20.0 * k) for k in range(3)) < 2.0
        if free[r, c] and not in_corridor and 5.0 < c * RESOLUTION < side - 5.0:
            cv2.circle(img, (c, r), int(rng.integers(1, 4)), 0, -1)
    cv2.imwrite(str(folder / "map.png"), img)
    meta = {
        "image": "map.png",
        "resolution": RESOLUTION,
        "origin": [0.0, 0.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    (folder / "map.yaml").write_text(yaml.safe_dump(meta))
    cams = [
        {
            "name": f"cam{k + 1}",
            "position": position,
            "view_direction": view,
            "f": 400.0,
            "cx": 159.5,
            "cy": 119.5,
            "image_size": [320, 240],
        }
        for k, (position, view) in enumerate(
            (
                ([side / 2, side / 2 + 7.0, 2.5], [0.0, -1.0, -0.45]),
                ([side / 2 - 14.0, side / 2 + 1.2, 2.5], [1.0, -0.2, -0.45]),
            )
        )
    ]
    (folder / "cameras.yaml").write_text(yaml.safe_dump(cams))
    return folder / "map.yaml", folder / "cameras.yaml"


def measure(
    name: str, grid: Path, cameras: Path, out: Path, start: tuple[float, float, float] | None
) -> list[str]:
    """One row of the table (see the module)."""
    from twin.planning.boxes import boxed_space
    from twin.planning.maps import load_map
    from twin.planning.site_file import write_site
    from twin.scenario import load_scenario
    from twin.scenario.map_space import _map_boxes
    from twin.sim.render import CameraRenderer
    from twin.sim.world import build_world

    t0 = time.perf_counter()
    floor = load_map(grid)
    t1 = time.perf_counter()
    written = write_site(grid, cameras, out, start=start, predict=False)
    t2 = time.perf_counter()
    boxed = boxed_space(floor, written.plan.pose)
    t3 = time.perf_counter()
    _map_boxes.cache_clear()
    t4 = time.perf_counter()
    sc = load_scenario(out)
    t5 = time.perf_counter()
    world = build_world(sc)
    t6 = time.perf_counter()
    frames = []
    with CameraRenderer(world) as renderer:
        camera = sc.cameras[0].name
        renderer.render(camera)
        for _ in range(5):
            a = time.perf_counter()
            renderer.render(camera)
            frames.append(time.perf_counter() - a)
    x, y, _ = sc.space.size
    return [
        name,
        f"{x:.0f} x {y:.0f}",
        str(len(boxed.boxes)),
        f"{t1 - t0:.2f}",
        f"{t2 - t1:.1f}",
        f"{t3 - t2:.2f}",
        f"{t5 - t4:.2f}",
        f"{t6 - t5:.2f}",
        f"{1e3 * statistics.median(frames):.1f}",
        f"{out.stat().st_size / 1024:.0f}",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hospital", type=int, nargs="*", default=[10, 30])
    parser.add_argument("--side", type=float, default=60.0)
    args = parser.parse_args()
    from twin.planning.sample_floor import write_floor

    table = Table(title="map-backed spaces (one process)")
    for col in (
        "floor",
        "size [m]",
        "boxes",
        "read map [s]",
        "plan [s]",
        "lay boxes [s]",
        "load scenario [s]",
        "compile [s]",
        "render [ms]",
        "file [KiB]",
    ):
        table.add_column(col, justify="right")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.hospital:
            grid, cams = write_floor(f"{tmp}/h{n}", n)
            table.add_row(
                *measure(f"hospital, {n} cameras", grid, cams, Path(tmp, f"h{n}.toml"), None)
            )
        grid, cams = square_floor(Path(tmp, "square"), args.side)
        name = f"square {args.side:g} m"
        table.add_row(
            *measure(
                name, grid, cams, Path(tmp, "square.toml"), (args.side / 2, args.side / 2, 0.0)
            )
        )
    console = Console()
    console.print(table)
    console.print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
