"""The simulated clock: the world's time, plus time that passes without physics."""

from __future__ import annotations

from twin.hal.devices import Clock
from twin.sim.world import World
from twin.timing import timed


class SimClock(Clock):
    """Time of a simulated run, s.

    Args:
        world: the world.
        physics: whether :meth:`sleep` steps the world (render fidelity) or only counts
            the time (geometric fidelity, where nothing moves between commands).
        timings: accumulates wall time spent stepping the world under ``physics``.
    """

    def __init__(self, world: World, physics: bool, timings: dict[str, float]) -> None:
        self.world = world
        self.physics = physics
        self.timings = timings
        self._start = world.time
        self._extra = 0.0

    def now(self) -> float:
        return self.world.time - self._start + self._extra

    def sleep(self, seconds: float) -> None:
        if seconds < 0:
            raise ValueError(f"cannot sleep a negative time, got {seconds} s")
        if self.physics:
            with timed(self.timings, "physics"):
                self.world.run(seconds)
        else:
            self.pass_time(seconds)

    def pass_time(self, seconds: float) -> None:
        """Let ``seconds`` pass on this clock without stepping the world."""
        self._extra += float(seconds)
