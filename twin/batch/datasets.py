"""A data set as the trials of a batch take it: its stops' LED points, pixels and
covariances, and which LEDs a trial gives up at a stop."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from twin.instruments.marker_pose import survey_layout


@dataclass
class DataSet:
    """A data set's stops in the trials that took it (``rows``; ``alive``: those that have
    not started again since), in order: each stop's k <= N_led LED points."""

    rows: NDArray[np.intp]
    alive: NDArray[np.bool_]
    points: list[NDArray[np.float64]] = field(default_factory=list)  # (R, k, 3) each
    pixels: list[NDArray[np.float64]] = field(default_factory=list)  # (R, k, 2) each
    covariances: list[NDArray[np.float64]] = field(default_factory=list)  # (R, 3N_led, 3N_led)
    leds: list[NDArray[np.intp]] = field(default_factory=list)  # (k,) each: which LEDs
    children: list[str] = field(default_factory=list)  # each stop's child
    surveys: list[NDArray[np.float64]] = field(default_factory=list)  # (R, 3N_led, M) each
    size: int | None = None

    def arrays(self, n: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(R, n, 3) points and (R, n, 2) pixels, the first n LED points in order."""
        if not self.points:
            return np.zeros((0, 0, 3)), np.zeros((0, 0, 2))
        pts = np.concatenate(self.points, axis=1)
        pix = np.concatenate(self.pixels, axis=1)
        n = pts.shape[1] if n is None else n
        return pts[:, :n], pix[:, :n]

    def stops(self) -> NDArray[np.float64]:
        """(R, S, 3N_led, 3N_led) the covariance of each stop's LEDs, all N_led of them
        (the joint covariance of the data set is block-diagonal: one block a stop)."""
        return np.stack(self.covariances, axis=1)

    def shared(self) -> NDArray[np.float64] | None:
        """(R, S 3N_led, C M) the stops' loadings on their children's surveying errors in
        the layout of :meth:`stops` (None where the assembly is known exactly)."""
        if not self.covariances:
            return None
        return survey_layout(self.children, self.surveys, self.covariances[0].shape[-1])

    def slots(self) -> NDArray[np.intp]:
        """(n,) where each LED point sits in the layout of :meth:`stops` (S stops of N_led
        LEDs): ``s N_led + led``; ``arange(n)`` when every stop holds every LED."""
        if not self.leds:
            return np.zeros(0, dtype=np.intp)
        n_led = self.covariances[0].shape[-1] // 3
        return np.concatenate([s * n_led + leds for s, leds in enumerate(self.leds)])


def missed(seen: NDArray[np.bool_], partial: bool) -> NDArray[np.bool_]:
    """(T, k) which of a stop's k planned LEDs each trial gives up, from (T, k) which it
    found: where the stop's plan is ``partial`` only the LEDs it missed (as the campaign
    does), else a trial that misses one gives up the whole stop. Either counts one failure
    a stop."""
    if partial:
        return ~seen
    lost = ~seen.all(axis=1)
    return np.broadcast_to(lost[:, None], seen.shape)
