"""The reference route as a path: arc length, points and headings along it."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray


class RoutePath:
    """A polyline on the floor, walked by arc length.

    Args:
        waypoints: (K, 2) points, m, K >= 2. Beyond its ends the path goes on straight.
    """

    def __init__(self, waypoints: ArrayLike) -> None:
        p = np.asarray(waypoints, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise ValueError(f"waypoints must be (K >= 2, 2), got {p.shape}")
        seg = np.diff(p, axis=0)
        lengths = np.linalg.norm(seg, axis=1)
        keep = np.concatenate([[True], lengths > 1e-9])
        self.points = p[keep]
        seg = np.diff(self.points, axis=0)
        self.lengths = np.linalg.norm(seg, axis=1)
        self.directions = seg / self.lengths[:, None]
        self.starts = np.concatenate([[0.0], np.cumsum(self.lengths)])

    @property
    def length(self) -> float:
        """Total length, m."""
        return float(self.starts[-1])

    def _segment(self, s: float) -> int:
        return int(
            np.clip(np.searchsorted(self.starts, s, side="right") - 1, 0, len(self.lengths) - 1)
        )

    def at(self, s: float) -> NDArray[np.float64]:
        """(2,) the point at arc length ``s``, m (straight on beyond the ends)."""
        i = self._segment(s)
        return self.points[i] + (s - self.starts[i]) * self.directions[i]

    def heading(self, s: float) -> float:
        """Direction of travel at arc length ``s``, rad."""
        d = self.directions[self._segment(s)]
        return math.atan2(d[1], d[0])

    def offset(self, s: float, lateral: float) -> NDArray[np.float64]:
        """(2,) the point ``lateral`` m to the left of the path at ``s``."""
        h = self.heading(s)
        return self.at(s) + lateral * np.array([-math.sin(h), math.cos(h)])

    def project(
        self,
        xy: ArrayLike,
        near: float | None = None,
        window: float = 20.0,
        tie: float = 1e-9,
    ) -> float:
        """Arc length of the path's point nearest to ``xy``, m; with ``near``, only the part
        of the path within ``window`` m of arc length ``near`` is searched (a path that comes
        back past itself has two nearest points).

        The path goes on straight beyond its ends: a point nearest to that straight
        continuation (within the window, measured along the continuation) projects to the
        end it continues, not to another part of a path that comes back near its end.

        Where the path passes within ``tie`` m of the nearest distance at more than one arc
        length (a route that comes back along itself: out to a turn and back on the same
        line), the one nearest in arc length to ``near`` is taken (without ``near``, the
        first along the path). Taking the first whatever ``near`` put a group on its way
        back onto the way out, and it drove round the turn again, leg after leg."""
        q = np.asarray(xy, dtype=float).reshape(2)
        lo, hi = (-math.inf, math.inf) if near is None else (near - window, near + window)
        found: list[tuple[float, float]] = []  # (arc length, distance), in path order
        # The segments that reach into the window (a long route has hundreds).
        first = self.starts[:-1]
        inside = np.minimum(self.lengths, hi - first) >= np.maximum(0.0, lo - first)
        for i in np.flatnonzero(inside):
            a, d, n = self.points[i], self.directions[i], self.lengths[i]
            t_lo = max(0.0, lo - self.starts[i])
            t_hi = min(n, hi - self.starts[i])
            t = float(np.clip((q - a) @ d, t_lo, t_hi))
            found.append((self.starts[i] + t, float(np.linalg.norm(a + t * d - q))))
        for end, s_end, sign in ((0, 0.0, -1.0), (-1, self.length, 1.0)):
            if not lo <= s_end <= hi:
                continue
            d = self.directions[end]
            beyond = sign * float((q - self.points[end]) @ d)
            # The continuation's own arc length is searched too: a point far beyond the
            # route's end is not near a group at ``near`` (a route that ends pointing back at
            # where the group stands, through a wall).
            if beyond > 0.0 and lo <= s_end + sign * beyond <= hi:
                found.append(
                    (s_end, float(np.linalg.norm(self.points[end] + sign * beyond * d - q)))
                )
        if not found:
            return float(np.clip(near, 0.0, self.length)) if near is not None else 0.0
        nearest = min(dist for _, dist in found)
        close = [s for s, dist in found if dist <= nearest + max(tie, 1e-9)]
        if near is None:
            return float(close[0])
        return float(min(close, key=lambda s: abs(s - near)))

    def vertices_between(self, s0: float, s1: float) -> list[NDArray[np.float64]]:
        """The path's corners strictly between arc lengths ``s0`` and ``s1`` (in travel
        order), so that a robot following the path turns there."""
        inner = self.starts[1:-1]
        idx = np.flatnonzero((inner > min(s0, s1) + 1e-6) & (inner < max(s0, s1) - 1e-6)) + 1
        if s1 < s0:
            idx = idx[::-1]
        return [self.points[i].copy() for i in idx]
