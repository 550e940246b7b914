"""Speed of the plan geometry on the footprints of shipped scenarios: the clearance test the
campaign asks many times per decision (``robot_fits``: walls and every obstacle, through
shapely), against its baseline, the same test done per obstacle in the obstacle's own frame
with numpy; and the search for obstacles near a set of points.

Printed per scenario and number of floor points (drawn uniformly inside the walls, seed
0): microseconds per call, best of ``--repeat`` rounds, and the ratio to the baseline.

    .venv/bin/python benchmarks/bench_geometry.py [--repeat 7] [--scenarios F ...]
"""

from __future__ import annotations

import argparse
import math
import timeit
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from twin.campaign.plan.clearance import ROBOT_CLEARANCE, robot_fits
from twin.scenario import load_scenario
from twin.scenario.geometry import inside_space, obstacles_near
from twin.scenario.schema import Space

ROOT = Path(__file__).resolve().parents[1]
POINTS = (1, 10, 50, 1600)
"""Numbers of floor points: a goal, a formation's places, a leg's places, and a camera's
candidate places (a grid over its image at four heights)."""


def robot_fits_numpy(space: Space, points_xy: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The baseline: :func:`robot_fits` with each obstacle's test in its own frame."""
    ok = inside_space(space, points_xy, ROBOT_CLEARANCE)
    for ob in space.obstacles:
        c, s = math.cos(ob.yaw), math.sin(ob.yaw)
        dx = points_xy[:, 0] - ob.center[0]
        dy = points_xy[:, 1] - ob.center[1]
        hx, hy = 0.5 * ob.size[0] + ROBOT_CLEARANCE, 0.5 * ob.size[1] + ROBOT_CLEARANCE
        ok &= ~((np.abs(c * dx + s * dy) <= hx) & (np.abs(-s * dx + c * dy) <= hy))
    return ok


def per_call(f: Callable[[], object], repeat: int) -> float:
    """Microseconds per call of ``f``, best of ``repeat`` rounds of about 20 ms."""
    timer = timeit.Timer(f)
    number, _ = timer.autorange()
    number = max(1, number // 10)
    return min(timer.repeat(repeat=repeat, number=number)) / number * 1e6


def table(path: str, repeat: int) -> None:
    """Print the times on the scenario at ``path``."""
    space = load_scenario(path).space
    (x0, x1), (y0, y1) = space.x_range, space.y_range
    rng = np.random.default_rng(0)
    print(f"\n{Path(path).name}: {len(space.obstacles)} obstacles, us per call")
    print(f"{'points':>8}{'robot_fits':>12}{'numpy':>10}{'ratio':>8}{'obstacles_near':>16}")
    for n in POINTS:
        p = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
        assert np.array_equal(robot_fits(space, p), robot_fits_numpy(space, p))
        fits = per_call(lambda p=p: robot_fits(space, p), repeat)
        base = per_call(lambda p=p: robot_fits_numpy(space, p), repeat)
        near = per_call(lambda p=p: obstacles_near(space.obstacles, p, 0.29), repeat)
        print(f"{n:>8}{fits:>12.1f}{base:>10.1f}{fits / base:>8.2f}{near:>16.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument(
        "--scenarios",
        nargs="+",
        default=[str(ROOT / "scenarios" / f) for f in ("paper_hall.toml", "hospital_floor.toml")],
    )
    args = parser.parse_args()
    for path in args.scenarios:
        table(path, args.repeat)


if __name__ == "__main__":
    main()
