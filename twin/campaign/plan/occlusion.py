"""Prisms hidden by their own assembly: the mast, the arms that hold the prisms, or another
prism can stand between the total station and a prism, and a child may have to turn to
show all three (:func:`unhidden_yaw`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.campaign.plan.clearance import body_points

MAST_RADIUS = 0.02
"""The mast's radius with a margin, m (the assembly's mast stands on the body axis up to
the prisms' height)."""

ARM_RADIUS = 0.015
"""An arm's radius with a margin, m (arms run from the mast to each prism, just below it)."""

PRISM_RADIUS = 0.04
"""A prism housing's radius with a margin, m."""

OWN_HOUSING = 0.045
"""The last part of a line of sight, m, that ends in the prism's own housing."""


def _segment_distance(points: NDArray, a: NDArray, b: NDArray) -> NDArray:
    """(N,) distances of (N, 3) points to the segment a-b."""
    d = b - a
    t = np.clip((points - a) @ d / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * d), axis=1)


def segments_distance(p0: ArrayLike, p1: ArrayLike, q0: ArrayLike, q1: ArrayLike) -> NDArray:
    """(...) least distances between the (..., 3) segments p0-p1 and q0-q1, m (either may
    be a point).

    With ``r = p0 - q0``, ``u = p1 - p0`` and ``w = q1 - q0``, the squared distance of the
    points at ``s`` and ``t`` along them is a quadratic in (s, t) on the unit square. Its
    least value lies at the closest points of the lines if both fall inside the segments,
    else at an end of one of them. Segments within 1e-6 rad of parallel (whose closest
    points are ill-conditioned) are measured at their ends only, which overestimates their
    distance by less than 1e-6 of their lengths. The squared distance is formed as a sum of
    terms of the size of ``|r|^2``: a distance near 0 comes out as up to about 1e-8 ``|r|``.
    """
    p0, p1, q0, q1 = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p0, p1, q0, q1)))
    shape = p0.shape[:-1]
    # (3, N) coordinates: sums over the first axis are fast.
    p0, p1, q0, q1 = (x.reshape(-1, 3).T for x in (p0, p1, q0, q1))
    u, w, r = p1 - p0, q1 - q0, p0 - q0
    a, b, c = (u * u).sum(0), (u * w).sum(0), (w * w).sum(0)
    d, e, f = (u * r).sum(0), (w * r).sum(0), (r * r).sum(0)
    b2, d2, e2 = 2.0 * b, 2.0 * d, 2.0 * e
    # Squared distance at (s, t): s (a s + 2 d - 2 b t) + t (c t - 2 e) + f.
    a_pos, c_pos = np.maximum(a, 1e-300), np.maximum(c, 1e-300)
    t = _unit(e / c_pos)  # from p0
    least = t * (c * t - e2) + f
    t = _unit((b + e) / c_pos)  # from p1
    least = np.minimum(least, (a + d2 - b2 * t) + t * (c * t - e2) + f)
    s = _unit(-d / a_pos)  # from q0
    least = np.minimum(least, s * (a * s + d2) + f)
    s = _unit((b - d) / a_pos)  # from q1
    least = np.minimum(least, s * (a * s + d2 - b2) + (c - e2) + f)
    den = a * c - b * b
    inner = den > 1e-12 * a * c
    den = np.where(inner, den, 1.0)
    s, t = (b * e - c * d) / den, (a * e - b * d) / den
    inner &= (s >= 0.0) & (s <= 1.0) & (t >= 0.0) & (t <= 1.0)
    between = s * (a * s + d2 - b2 * t) + t * (c * t - e2) + f
    least = np.where(inner, np.minimum(least, between), least)
    return np.sqrt(np.maximum(least, 0.0)).reshape(shape)


def _unit(x: NDArray) -> NDArray:
    """``x`` clipped to [0, 1]."""
    return np.minimum(np.maximum(x, 0.0), 1.0)


SIGHT_SAMPLES = 0.6
"""Length of the last part of a line of sight that is tested against the assembly, m (the
assembly is 0.2 m across)."""

SIGHT_STEP = 0.002
"""Spacing of the points along it that are tested, m."""

PRUNE_MARGIN = 1e-4
"""A part of the assembly farther than its radius and this (m) from a whole line of sight
is farther than its radius from every tested point of it."""


def _sight_points(eye: NDArray, target: NDArray) -> NDArray:
    """(M, 3) the tested points of the line of sight from (3,) ``eye`` to (3,) ``target``:
    every ``SIGHT_STEP`` along its last ``SIGHT_SAMPLES``, short of the target's own
    housing (``OWN_HOUSING``), m."""
    v = target - eye
    n = float(np.linalg.norm(v))
    t = np.arange(max(n - SIGHT_SAMPLES, 0.0), n - OWN_HOUSING, SIGHT_STEP)
    return eye + np.outer(t / n, v)


def _assembly_parts(base: NDArray, cubes: NDArray) -> tuple[NDArray, NDArray]:
    """The parts of Y assemblies that can hide a prism, as segments (a prism is a segment
    of length 0): the mast, the K arms (from the mast to just below each prism), the K
    prisms.

    Args:
        base: (3,) the mast's foot, m (W). cubes: (Y, K, 3) the prisms of Y assemblies, m.

    Returns:
        (Y, 1 + 2 K, 3) starts and ends of the parts, m.
    """
    n_y, n_k = cubes.shape[:2]
    starts = np.empty((n_y, 1 + 2 * n_k, 3))
    ends = np.empty_like(starts)
    starts[:, 0] = base
    ends[:, 0] = [base[0], base[1], float(cubes[:, :, 2].max())]
    arms = slice(1, 1 + n_k)
    starts[:, arms, :2] = base[:2]
    ends[:, arms, :2] = cubes[:, :, :2]
    starts[:, arms, 2] = ends[:, arms, 2] = cubes[:, :, 2] - 0.02
    starts[:, 1 + n_k :] = ends[:, 1 + n_k :] = cubes
    return starts, ends


def _part_radii(n_k: int) -> tuple[NDArray, NDArray]:
    """(1 + 2 K,) radius of each part of :func:`_assembly_parts`, m, and (1 + 2 K,) the
    prism each part is (-1 for the mast and the arms)."""
    radii = np.array([MAST_RADIUS] + [ARM_RADIUS] * n_k + [PRISM_RADIUS] * n_k)
    return radii, np.array([-1] * (1 + n_k) + list(range(n_k)))


@dataclass(frozen=True)
class _Sights:
    """The lines of sight from E instruments to the K prisms of an assembly at Y headings,
    with the parts of the assembly that come near each (see :func:`_sights`).

    Attributes:
        eyes: (E, 3) m. cubes: (Y, K, 3) m. starts, ends: (Y, P, 3) the parts, m.
        radii: (P,) m. prism: (P,) which prism a part is (-1: none).
        near: (Y, E, K, P) whether a part comes within its radius and ``PRUNE_MARGIN`` of
            the tested part of a line of sight.
    """

    eyes: NDArray
    cubes: NDArray
    starts: NDArray
    ends: NDArray
    radii: NDArray
    prism: NDArray
    near: NDArray

    def hidden(self, i: int, e: int, k: int) -> bool:
        """Whether a part of the assembly at heading ``i`` comes closer than its radius to
        a tested point of the line of sight from eye ``e`` to prism ``k``."""
        parts = np.flatnonzero(self.near[i, e, k])
        if parts.size == 0:
            return False
        ray = _sight_points(self.eyes[e], self.cubes[i, k])
        for j in parts:
            if self.prism[j] >= 0:
                gap = np.linalg.norm(ray - self.starts[i, j], axis=1)
            else:
                gap = _segment_distance(ray, self.starts[i, j], self.ends[i, j])
            if gap.min() < self.radii[j]:
                return True
        return False


def _sights(
    xy: ArrayLike, yaws: ArrayLike, cubes_body: ArrayLike, viewers: ArrayLike, floor_z: float
) -> _Sights:
    """The lines of sight from (E, 3) ``viewers`` (m, W) to the prisms of a child at
    ``xy`` (m) for each of (Y,) ``yaws`` (rad), and the parts that come near them."""
    y = np.asarray(yaws, dtype=float).reshape(-1)
    eyes = np.asarray(viewers, dtype=float).reshape(-1, 3)
    p = np.asarray(xy, dtype=float).reshape(2)
    cubes = body_points(np.broadcast_to(p, (len(y), 2)), y, cubes_body, floor_z)
    starts, ends = _assembly_parts(np.array([p[0], p[1], floor_z]), cubes)
    radii, prism = _part_radii(cubes.shape[1])
    # The tested part of each line of sight, (Y, E, K, 1, 3), against each part.
    target = cubes[:, None, :, None, :]
    eye = eyes[None, :, None, None, :]
    v = target - eye
    n = np.sqrt((v * v).sum(-1, keepdims=True))
    s0 = eye + np.maximum(n - SIGHT_SAMPLES, 0.0) / n * v
    s1 = eye + (n - OWN_HOUSING) / n * v
    gap = segments_distance(s0, s1, starts[:, None, None], ends[:, None, None])
    near = (gap < radii + PRUNE_MARGIN) & (prism != np.arange(cubes.shape[1])[:, None])
    return _Sights(eyes, cubes, starts, ends, radii, prism, near)


def prisms_hidden_many(
    xy: ArrayLike,
    yaws: ArrayLike,
    cubes_body: ArrayLike,
    viewers: ArrayLike,
    floor_z: float,
) -> NDArray[np.bool_]:
    """(Y, E, K) whether each of the K prisms of a child at ``xy`` is hidden by the
    assembly itself from each of E instruments ((E, 3) ``viewers``, m, W), for each of Y
    headings ((Y,) ``yaws``, rad): :func:`prisms_hidden` for each."""
    sights = _sights(xy, yaws, cubes_body, viewers, floor_z)
    hidden = np.zeros(sights.near.shape[:3], dtype=bool)
    for i, e, k in np.argwhere(sights.near.any(axis=-1)):
        hidden[i, e, k] = sights.hidden(i, e, k)
    return hidden


def prisms_hidden(
    xy: ArrayLike,
    yaw: float,
    cubes_body: ArrayLike,
    viewer: ArrayLike,
    floor_z: float,
) -> NDArray[np.bool_]:
    """(3,) whether each prism of a child at ``xy``, ``yaw`` is hidden from the instrument
    at ``viewer`` ((3,) m, W) by the assembly itself: its mast, the arms that hold the
    prisms, or another prism (they all stand at about one height, so at a grazing view one
    can stand in front of another).

    The line of sight is tested every ``SIGHT_STEP`` along its last ``SIGHT_SAMPLES``
    (short of the prism's own housing), against the parts of the assembly that come
    within their radius and ``PRUNE_MARGIN`` of it."""
    return prisms_hidden_many(xy, [yaw], cubes_body, viewer, floor_z)[0, 0]


def unhidden_yaw(
    xy: ArrayLike,
    yaw: float,
    cubes_body: ArrayLike,
    viewers: ArrayLike,
    floor_z: float,
    max_turn_deg: float = 90.0,
) -> float | None:
    """The heading nearest ``yaw`` (in 10 deg steps up to ``max_turn_deg``) at which no
    prism is hidden from any viewer ((K, 3) instrument positions, m); None if none is."""
    turns = np.arange(10.0, max_turn_deg + 1e-9, 10.0)
    steps = [0.0, *np.ravel(np.column_stack([turns, -turns]))]
    yaws = np.array([yaw + np.radians(step) for step in steps])
    sights = _sights(xy, yaws, cubes_body, viewers, floor_z)
    near = sights.near.any(axis=-1)
    for i in range(len(yaws)):
        lines = np.argwhere(near[i])
        if not any(sights.hidden(i, e, k) for e, k in lines):
            return float(yaws[i])
    return None
