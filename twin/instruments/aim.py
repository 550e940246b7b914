"""Automatic aim: the instrument searches a cone around its pointing direction.

The instrument is pointed at a predicted prism position. It locks onto a prism only if one
lies within ``spec.aim_cone`` of the pointing direction, and then onto the one closest in
angle to the pointing direction, which is the wrong prism whenever the prediction is closer
in angle to another prism (e.g. the three cubes of one child seen from far away).

Candidates are filtered in this order, and the failure names the stage that left none:

1. inside the search cone, else :class:`NoPrismInConeError`;
2. line of sight clear (a callback supplied by the simulation or a map), else
   :class:`LineOfSightBlockedError` (a blocked prism returns no signal, so the instrument
   may lock onto another visible prism in the cone);
3. the closest remaining prism in angle is locked; if its slope distance is outside
   [range_min, range_max] the shot fails with :class:`OutOfRangeError`.

Out-of-range prisms compete for the lock like any other: the instrument locks onto the
return closest to its pointing direction before it measures a distance, so it cannot pass
over a prism for being too near or too far. A too-near or too-far prism that is closer in
angle than the wanted one therefore fails the shot with :class:`OutOfRangeError` (naming
the locked prism) rather than letting the aim fall back to another prism: the caller
learns why, and no shot silently lands on a prism it did not choose.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.instruments.errors import (
    LineOfSightBlockedError,
    NoPrismInConeError,
    OutOfRangeError,
)
from twin.instruments.total_station import TotalStationSpec

LineOfSight = Callable[[int, NDArray[np.float64]], bool]
"""Callback ``(prism_index, prism_position_instrument (3,) m) -> True if visible``."""


def angles_from_direction(points: ArrayLike, direction: ArrayLike) -> NDArray[np.float64]:
    """Angles, rad, between (N, 3) points (seen from the origin) and a (3,) direction."""
    p = np.asarray(points, dtype=float)
    u = np.asarray(direction, dtype=float)
    u = u / np.linalg.norm(u)
    n = np.linalg.norm(p, axis=-1)
    cos = np.einsum("...i,i->...", p, u) / n
    # |p x u|: np.cross's products and np.linalg.norm's sum, without their overhead.
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    cx, cy, cz = y * u[2] - z * u[1], z * u[0] - x * u[2], x * u[1] - y * u[0]
    sin = np.sqrt(cx * cx + cy * cy + cz * cz) / n
    return np.arctan2(sin, cos)


def auto_aim(
    prisms: ArrayLike,
    pointing: ArrayLike,
    spec: TotalStationSpec,
    line_of_sight: LineOfSight | None = None,
) -> int:
    """Index of the prism the automatic aim locks onto.

    Args:
        prisms: (N, 3) true prism positions in the instrument frame, m.
        pointing: (3,) predicted position (or direction) the instrument is pointed at, in the
            instrument frame, m.
        spec: instrument specification (``aim_cone``, ``range_min``, ``range_max``).
        line_of_sight: optional visibility callback; None means every prism is visible.

    Returns:
        Row index into ``prisms``.

    Raises:
        NoPrismInConeError, LineOfSightBlockedError, OutOfRangeError: see the module text.
        ValueError: malformed input.
    """
    p = np.asarray(prisms, dtype=float)
    if p.ndim == 1 and p.shape == (3,):
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] == 0:
        raise ValueError(f"prisms must have shape (N, 3) with N >= 1, got {p.shape}")
    u = np.asarray(pointing, dtype=float)
    if u.shape != (3,) or not np.all(np.isfinite(u)) or not np.any(u):
        raise ValueError(f"pointing must be a finite non-zero (3,) vector, got {u}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"prisms contain NaN or inf: {p}")
    distances = np.linalg.norm(p, axis=1)
    if np.any(distances == 0):
        raise ValueError("a prism lies at the instrument centre")

    angles = angles_from_direction(p, u)
    in_cone = np.flatnonzero(angles <= spec.aim_cone)
    if in_cone.size == 0:
        raise NoPrismInConeError(
            f"no prism within {np.degrees(spec.aim_cone):.2f} deg of the pointing direction; "
            f"the closest is {np.degrees(angles.min()):.2f} deg away",
            closest_angle=float(angles.min()),
        )
    visible = [int(i) for i in in_cone if line_of_sight is None or line_of_sight(int(i), p[i])]
    if not visible:
        raise LineOfSightBlockedError(
            f"{in_cone.size} prism(s) in the search cone but the line of sight to each is blocked",
            blocked=tuple(int(i) for i in in_cone),
        )
    locked = min(visible, key=lambda i: angles[i])
    d = distances[locked]
    if not spec.range_min <= d <= spec.range_max:
        raise OutOfRangeError(
            f"locked prism {locked} is at {d:.3f} m, outside the measurable range "
            f"[{spec.range_min}, {spec.range_max}] m",
            distance=float(d),
            prism_index=locked,
        )
    return locked
