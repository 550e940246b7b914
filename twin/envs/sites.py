"""Random sites for the environment: corridors and halls with obstacles and cameras, drawn
from a generator, so that a policy does not learn one hall only.

Every site is a scenario checked as a scenario file is (:func:`twin.scenario.loader.
scenario_from_dict`: the robots stand free, every camera's station sees at least
``calibration.min_visible_fraction`` of its view). A draw that fails the checks is drawn
again from the same generator, so a seed always gives the same site.

- ``corridor``: 30-55 m long, 2.4-3.6 m wide, pilasters along the walls, 2-3 cameras near
  the ceiling looking along it, the route down its middle (the paper's Fig. 6);
- ``hall``: 30-50 m by 10-15 m, a free-standing island between the two legs of a U-shaped
  route and structures along the far wall, 2-4 cameras on the long walls looking across.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from twin.scenario.loader import scenario_from_dict
from twin.scenario.schema import Scenario

__all__ = ["KINDS", "random_site"]

KINDS = ("corridor", "hall")
"""The kinds of random site."""

ATTEMPTS = 100
"""Draws tried before giving up on a site."""

FLOOR_Z = -0.40
"""The floor below the parent's instrument at its start, m (as the paper's hall)."""

CAMERA_HEIGHT = 2.4
"""Cameras hang this far above the floor, m."""

CORRIDOR_STATION_BEHIND = 2.0
"""A corridor camera's station lies this far behind it (against the direction it looks), m:
the total station then sees the camera's whole view down the corridor (measured on 12
corridors: every camera calibrated, against 75 % with the station 1 m past the camera)."""

_INTRINSICS = {"f": 770.0, "cx": 159.5, "cy": 119.5, "image_size": [320, 240]}


def _camera(name: str, xyz: list[float], direction: list[float]) -> dict[str, Any]:
    return {"name": name, "position": xyz, "view_direction": direction, **_INTRINSICS}


def _robots() -> dict[str, Any]:
    return {
        "parent": {"name": "parent", "model": "pioneer3at", "start_xy": [0.0, 0.0]},
        "children": [
            {"name": "child1", "model": "pioneer3dx", "start_xy": [3.0, 0.5]},
            {"name": "child2", "model": "pioneer3dx", "start_xy": [6.0, -0.5]},
        ],
    }


def _site(
    name: str,
    description: str,
    seed: int,
    space: dict[str, Any],
    cameras: list[dict[str, Any]],
    route: list[list[float]],
    visits: list[dict[str, Any]],
) -> dict[str, Any]:
    """A scenario's fields: the space (the floor at :data:`FLOOR_Z`), the cameras, the
    robots at their usual start, the route and the visits."""
    return {
        "name": name,
        "description": description,
        "seed": seed,
        "space": {**space, "floor_z": FLOOR_Z},
        "cameras": cameras,
        "robots": _robots(),
        "route": {"waypoints": route},
        "calibration": {"visits": visits},
    }


def _corridor(rng: np.random.Generator, seed: int) -> dict[str, Any]:
    length = float(rng.uniform(30.0, 55.0))
    width = float(rng.uniform(2.4, 3.6))
    half = width / 2
    end = length - 6.0  # the route's end, m from the start
    obstacles = []
    for k, x in enumerate(np.arange(10.0, length - 4.0, float(rng.uniform(8.0, 14.0)))):
        side = 1.0 if rng.random() < 0.5 else -1.0
        obstacles.append(
            {
                "name": f"pilaster_{k}",
                "center": [float(x), side * (half - 0.15)],
                "size": [0.4, 0.3, 3.0],
            }
        )
    n = int(rng.integers(2, 4))
    cameras, visits = [], []
    for k, x in enumerate(np.linspace(8.0, end - 4.0, n) + rng.uniform(-1.5, 1.5, n)):
        ahead = 1.0 if rng.random() < 0.6 else -1.0  # looking along +x or -x
        side = -1.0 if rng.random() < 0.5 else 1.0
        name = f"cam{k + 1}"
        cameras.append(
            _camera(
                name,
                [float(x), side * (half - 0.3), FLOOR_Z + CAMERA_HEIGHT],
                [0.90 * ahead, -0.15 * side, -0.42],
            )
        )
        station = float(np.clip(x - CORRIDOR_STATION_BEHIND * ahead, 0.5, end))
        visits.append({"camera": name, "station": [station, 0.0], "yaw_deg": 0.0})
    return _site(
        f"corridor_{seed}",
        "A random corridor with pilasters and cameras looking along it.",
        seed,
        {"size": [length, width, 3.0], "origin": [-3.0, -half], "obstacles": obstacles},
        cameras,
        [[0.0, 0.0], [end, 0.0]],
        visits,
    )


def _hall(rng: np.random.Generator, seed: int) -> dict[str, Any]:
    length = float(rng.uniform(30.0, 50.0))
    width = float(rng.uniform(10.0, 15.0))
    x0, y0 = -5.0, -2.0
    turn = length - 12.0  # the route's far corner, m
    lane = 4.0  # the route's return leg, m from the first
    island = float(rng.uniform(6.0, min(14.0, turn - 6.0)))
    obstacles = [
        {
            "name": "island",
            "center": [float(rng.uniform(4.0 + island / 2, turn - island / 2)), lane / 2],
            "size": [island, 1.8, 3.0],
        }
    ]
    for k in range(int(rng.integers(1, 3))):
        size = [float(rng.uniform(3.0, 8.0)), float(rng.uniform(2.0, 3.5)), 6.0]
        x = float(rng.uniform(x0 + size[0] / 2, x0 + length - size[0] / 2))
        obstacles.append(
            {"name": f"structure_{k}", "center": [x, y0 + width - size[1] / 2], "size": size}
        )
    n = int(rng.integers(2, 5))
    cameras, visits = [], []
    for k, x in enumerate(np.linspace(4.0, turn - 3.0, n) + rng.uniform(-2.0, 2.0, n)):
        south = k % 2 == 0
        name = f"cam{k + 1}"
        if south:  # on the near wall looking across at the first leg
            xyz, direction, station_y = (
                [float(x), y0 + 0.4, FLOOR_Z + CAMERA_HEIGHT],
                [0.0, 0.92, -0.38],
                0.0,
            )
        else:  # above the return leg, looking back across it
            xyz, direction, station_y = (
                [float(x), lane + 5.0, FLOOR_Z + CAMERA_HEIGHT],
                [0.0, -0.92, -0.38],
                lane,
            )
        cameras.append(_camera(name, xyz, direction))
        station = float(np.clip(x + 3.0 * (1 if south else -1), 0.5, turn - 0.5))
        yaw = 0.0 if south else 180.0
        visits.append({"camera": name, "station": [station, station_y], "yaw_deg": yaw})
    return _site(
        f"hall_{seed}",
        "A random hall with an island, structures and cameras on its walls.",
        seed,
        {"size": [length, width, 6.0], "origin": [x0, y0], "obstacles": obstacles},
        cameras,
        [[0.0, 0.0], [turn, 0.0], [turn, lane], [0.0, lane]],
        visits,
    )


_MAKERS = {"corridor": _corridor, "hall": _hall}


def random_site(rng: np.random.Generator, kind: str | None = None) -> Scenario:
    """A random site drawn from ``rng`` (see the module).

    Args:
        rng: the generator (an environment's ``np_random``).
        kind: ``corridor``, ``hall``, or None for either (drawn).

    Raises:
        ValueError: an unknown kind.
        RuntimeError: no draw passed the scenario's checks in :data:`ATTEMPTS` tries.
    """
    if kind is not None and kind not in _MAKERS:
        raise ValueError(f"unknown site kind {kind!r}; kinds: {', '.join(KINDS)}")
    last = ""
    for _ in range(ATTEMPTS):
        chosen = kind or KINDS[int(rng.integers(len(KINDS)))]
        seed = int(rng.integers(2**31))
        raw = _MAKERS[chosen](rng, seed)
        try:
            return scenario_from_dict(raw, f"<random {chosen} {seed}>")
        except ValueError as exc:
            last = str(exc).splitlines()[0]
    raise RuntimeError(f"no random {kind or 'site'} passed the checks in {ATTEMPTS} draws: {last}")
