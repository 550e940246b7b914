"""The total station on the simulated parent: its noise model, MuJoCo ray casts for the
line of sight, and injected lost locks."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from twin.hal.devices import Clock, TotalStation
from twin.hal.readings import TiltReading, TotalStationMeasurement
from twin.instruments.errors import NoPrismInConeError
from twin.instruments.shot import simulate_shot
from twin.instruments.tilt import read_inclinometer, tilt_from_orientation
from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.sim.rig.shot_noise import ShotNoise
from twin.sim.robots import N_CUBES
from twin.sim.world import World

PRISM_TOLERANCE = 0.04
"""A ray that stops within this distance of a prism (m) hits the prism's own housing (its
radius is 3 cm)."""


class SimTotalStation(TotalStation):
    """The parent's instrument in the world.

    Every child's corner cubes can answer the automatic aim (a wrong lock is possible, as
    on the real instrument); a cube whose line of sight is blocked in MuJoCo cannot.

    Args:
        world: the world. parent: the parent's name.
        spec, inclinometer: the instrument's noise.
        rng: noise of the shots and the tilt readings.
        clock: the rig's clock (timestamps).
        lost_lock_rate: probability that a shot fails to lock although a prism is there.
        fault_rng: random generator of the injected faults.
        advertised: the specification the instrument reports (:attr:`spec`,
            :attr:`inclinometer`), by which the campaign weighs its shots; default ``spec``
            and ``inclinometer``. An error budget simulates one noise source alone while
            the instrument still advertises them all.
        shot_noise: keyed measurement noise (:mod:`.shot_noise`); default: drawn from
            ``rng`` in turn.
    """

    def __init__(
        self,
        world: World,
        parent: str,
        spec: TotalStationSpec,
        inclinometer: InclinometerSpec,
        rng: np.random.Generator,
        clock: Clock,
        *,
        lost_lock_rate: float = 0.0,
        fault_rng: np.random.Generator | None = None,
        advertised: tuple[TotalStationSpec, InclinometerSpec] | None = None,
        shot_noise: ShotNoise | None = None,
    ) -> None:
        self.world = world
        self.parent = parent
        self._spec = spec
        self._inclinometer = inclinometer
        self.rng = rng
        self.clock = clock
        self.lost_lock_rate = lost_lock_rate
        self.fault_rng = fault_rng if fault_rng is not None else np.random.default_rng(0)
        self._aim: np.ndarray | None = None
        self.children = [c.name for c in world.scenario.robots.children]
        # Control points' prisms stand still; they answer the aim like the children's.
        self.controls = np.array(
            [p.position for p in world.scenario.control_points], dtype=float
        ).reshape(-1, 3)
        self._tilt: tuple[bytes, tuple[float, float]] = (b"", (0.0, 0.0))
        self._advertised = advertised or (spec, inclinometer)
        self.shot_noise = shot_noise

    @property
    def spec(self) -> TotalStationSpec:
        return self._advertised[0]

    @property
    def inclinometer(self) -> InclinometerSpec | None:
        return self._advertised[1]

    def point(self, target_level: ArrayLike) -> None:
        aim = np.asarray(target_level, dtype=float).reshape(3)
        if not np.all(np.isfinite(aim)) or not np.any(aim):
            raise ValueError(f"the aim must be a finite non-zero (3,) point, got {aim}")
        self._aim = aim

    def _true_state(self) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
        position, rotation = self.world.instrument_pose(self.parent)
        # The parent stands still for many shots: its tilt is worked out once per pose.
        key = rotation.tobytes()
        if key != self._tilt[0]:
            self._tilt = (key, tilt_from_orientation(rotation))
        return position, rotation, self._tilt[1]

    def measure(self) -> TotalStationMeasurement:
        if self._aim is None:
            raise RuntimeError("point the instrument at a prism before measuring")
        position, rotation, tilt = self._true_state()
        prisms_world = np.vstack(
            [self.world.marker_points(c)[0] for c in self.children] + [self.controls]
        )
        prisms = (prisms_world - position) @ rotation  # instrument frame
        now = self.clock.now()
        if self.lost_lock_rate > 0 and self.fault_rng.random() < self.lost_lock_rate:
            raise NoPrismInConeError(
                "the automatic aim lost the prism (injected fault)", injected=True
            )

        def clear(index: int, _position: np.ndarray) -> bool:
            return self.world.sensing.line_of_sight(
                position, prisms_world[index], self.parent, tolerance=PRISM_TOLERANCE
            )

        shot = simulate_shot(
            prisms,
            self._aim,
            self._spec,
            self.rng,
            true_tilt=tilt,
            inclinometer=self._inclinometer,
            line_of_sight=clear,
            timestamp=now,
            measurement_rng=None if self.shot_noise is None else self._keyed_noise,
        )
        return shot.measurement

    def _keyed_noise(self, index: int) -> np.random.Generator:
        """The measurement noise's generator for a shot that locked prism ``index``."""
        assert self.shot_noise is not None
        children = len(self.children) * N_CUBES
        if index >= children:  # a control point: keyed like a child that never moves
            i = index - children
            return self.shot_noise.generator(
                self.world.robot_pose(self.parent)[:2],
                len(self.children) + i,
                self.controls[i, :2],
                0,
            )
        child = index // N_CUBES
        return self.shot_noise.generator(
            self.world.robot_pose(self.parent)[:2],
            child,
            self.world.robot_pose(self.children[child])[:2],
            index % N_CUBES,
        )

    def read_inclination(self) -> TiltReading:
        _, _, tilt = self._true_state()
        return read_inclinometer(tilt[0], tilt[1], self._inclinometer, self.rng, self.clock.now())

    def close(self) -> None:
        """Nothing to release."""
