"""The robots of T trials as the batch simulates them: where each truly stands and where it
believes it stands, and the noise of what they do.

- a drive ends at the goal, moved by the base's error of localisation (where it truly stood
  against where it believed it stood) and by the scenario's stopping error; the standing
  children creep once per leg of the parent (their own stream: switching creep on changes
  no other draw);
- each child's marker assembly as built (its surveying error, for the whole trial);
- the total station's shots at a child's cubes: the instruments' own chain
  (:func:`twin.instruments.shot.shots_from_normals`) with the trials' draws.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z
from twin.batch.row_arrays import ALL, Rows, picked
from twin.batch.steps import BatchPlan, Drive, RobotTruth
from twin.batch.streams import CREEP_BATCH_STREAM, Draws
from twin.instruments.shot import shots_from_normals
from twin.instruments.tilt import tilt_from_orientation
from twin.scenario.schema import Noise


def compose(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) planar poses a (x) b: b expressed in the frame of a."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack(
        [
            a[:, 0] + c * b[:, 0] - s * b[:, 1],
            a[:, 1] + s * b[:, 0] + c * b[:, 1],
            a[:, 2] + b[:, 2],
        ]
    )


def inverse(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T, 3) inverse planar poses."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack([-(c * a[:, 0] + s * a[:, 1]), s * a[:, 0] - c * a[:, 1], -a[:, 2]])


@dataclass
class Robot:
    """A robot in T trials: where it truly stands and where it believes it stands (planar,
    (T, 3)), and each trial's stop in the noise-free plan (``nominal``: its pose, its
    marker's cubes and LEDs (a child), its instrument's centre, orientation and tilt (the
    parent), each (T, ...))."""

    true: NDArray[np.float64]
    believed: NDArray[np.float64]
    nominal: dict[str, NDArray[np.float64]]
    _stops: dict[int, tuple[RobotTruth, dict[str, NDArray[np.float64]]]] = field(
        default_factory=dict
    )

    @classmethod
    def at(cls, truth: RobotTruth, trials: int) -> Robot:
        pose = np.repeat(truth.pose[None], trials, axis=0)
        return cls(pose.copy(), pose.copy(), _nominal(truth, trials))

    def stopped(self, truths: Sequence[RobotTruth], rows: Rows) -> None:
        """The trials ``rows`` stopped at ``truths`` (one for all, or one a row)."""
        stops = [self._stop(t) for t in truths]
        for name, values in self.nominal.items():
            values[rows] = stops[0][name] if len(stops) == 1 else [s[name][0] for s in stops]

    def _stop(self, truth: RobotTruth) -> dict[str, NDArray[np.float64]]:
        """A stop's arrays, (1, ...) each (made once per stop: a plan's stops repeat)."""
        known = self._stops.get(id(truth))
        if known is None or known[0] is not truth:
            known = self._stops[id(truth)] = (truth, _nominal(truth, 1))
        return known[1]

    def moved(self, points: NDArray[np.float64], rows: Rows) -> NDArray[np.float64]:
        """(R, ..., 3) points of the trials' nominal stops (W) moved with their true poses.
        The robot's turn is about the vertical through its origin."""
        true, pose = self.true[rows], self.nominal["pose"][rows]
        r = rot_z(true[:, 2] - pose[:, 2])
        flat = points.reshape(len(true), -1, 3).copy()
        flat[..., :2] -= pose[:, None, :2]
        out = np.einsum("tij,tkj->tki", r, flat)
        out[..., :2] += true[:, None, :2]
        return out.reshape(points.shape)


def _nominal(truth: RobotTruth, trials: int) -> dict[str, NDArray[np.float64]]:
    """A robot's stop as arrays, each repeated for ``trials`` trials."""
    out = {"pose": truth.pose}
    if truth.cubes is not None and truth.leds is not None:
        out["cubes"], out["leds"] = truth.cubes, truth.leds
    if truth.instrument is not None and truth.instrument2world is not None:
        out["instrument"], out["orientation"] = truth.instrument, truth.instrument2world
        out["tilt"] = np.array(tilt_from_orientation(truth.instrument2world))
    return {k: np.repeat(np.asarray(v, dtype=float)[None], trials, axis=0) for k, v in out.items()}


class Fleet:
    """The robots of a plan in T trials, with the noise they simulate (see the module).

    Args:
        plan: the campaign's plan.
        noise: the noise the trials simulate.
        draws: the trials' draws (:mod:`twin.batch.streams`); each child's assembly as
            built takes its first ones.
        seeds: (T,) the trials' root seeds (the children's creep has its own stream).
    """

    def __init__(self, plan: BatchPlan, noise: Noise, draws: Draws, seeds: list[int]) -> None:
        self.plan, self.noise, self.draws, self.seeds = plan, noise, draws, seeds
        self.spec = noise.total_station.spec()
        self.inclinometer = noise.inclinometer.spec()
        self.n_leds = len(plan.scenario.marker.assembly().leds_body)
        t = len(seeds)
        self.robots = {name: Robot.at(truth, t) for name, truth in plan.start.items()}
        self.built: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self.leg_started = np.zeros(t, dtype=bool)
        self._creep_draws: Draws | None = None
        self._build(ALL)

    def _build(self, rows: Rows) -> None:
        """The trials' marker assemblies, each child's as built (its surveying error)."""
        sigma = self.noise.marker_geometry_m
        for child in self.plan.children:
            cubes = sigma * self.draws.take(3, 3, rows=picked(rows))
            leds = sigma * self.draws.take(self.n_leds, 3, rows=picked(rows))
            if child not in self.built:
                self.built[child] = (cubes, leds)
            else:
                self.built[child][0][rows], self.built[child][1][rows] = cubes, leds

    def restart(self, rows: NDArray[np.intp], seeds: Sequence[int]) -> None:
        """The trials ``rows`` start again from ``seeds``: every robot at its start, the
        assemblies built again."""
        self.draws.restart(rows, seeds)
        if self._creep_draws is not None:
            self._creep_draws.restart(rows, seeds)
        for name, truth in self.plan.start.items():
            robot = self.robots[name]
            robot.true[rows] = truth.pose
            robot.believed[rows] = truth.pose
            robot.stopped([truth], rows)
        self._build(rows)
        self.leg_started[rows] = False

    def start_centre(self, n: int) -> NDArray[np.float64]:
        """(n, 3) the instrument's centre at the first station, m (W)."""
        instrument = self.plan.start[self.plan.parent].instrument
        assert instrument is not None
        return np.repeat(instrument[None], n, axis=0)

    def drive(self, steps: Sequence[Drive], r: Rows) -> None:
        """One robot of the trials ``r`` drove: to ``steps[0]`` in all, or to ``steps[i]``
        in the i-th."""
        step = steps[0]
        robot = self.robots[step.robot]
        if len(steps) == 1:
            believed = np.repeat(step.believed[None], len(robot.true[r]), axis=0)
        else:
            believed = np.stack([s.believed for s in steps])
        offset = compose(robot.true[r], inverse(robot.believed[r]))
        true = compose(offset, believed)
        stop = self.noise.stopping
        true[:, :2] += stop.sigma_xy * self.draws.take(2, rows=picked(r))
        true[:, 2] += stop.sigma_yaw * self.draws.take(1, rows=picked(r))[:, 0]
        robot.true[r], robot.believed[r] = true, believed
        robot.stopped([s.truth for s in steps], r)
        creep = self.noise.child_creep_m
        if step.robot == self.plan.parent and creep > 0:
            # The standing children creep once per leg of the parent (twin.sim.rig.creep).
            index = np.arange(len(self.seeds))[r]
            fresh = index[~self.leg_started[index]]
            if len(fresh):
                self.leg_started[fresh] = True
                if self._creep_draws is None:
                    self._creep_draws = Draws(self.seeds, 0, stream=CREEP_BATCH_STREAM)
                rows = None if len(fresh) == len(self.seeds) else fresh
                for child in self.plan.children:
                    self.robots[child].true[fresh, :2] += creep * self._creep_draws.take(
                        2, rows=rows
                    )

    def instrument(self, r: Rows) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The instrument's true centre (R, 3), m, and orientation (R, 3, 3) in W."""
        parent = self.robots[self.plan.parent]
        nominal = parent.nominal
        centre = parent.moved(nominal["instrument"][r][:, None, :], r)[:, 0]
        turn = rot_z(parent.true[r, 2] - nominal["pose"][r, 2])
        return centre, turn @ nominal["orientation"][r]

    def cubes(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, 3, 3) the child's true cubes in W, its assembly's surveying error included."""
        robot = self.robots[child]
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[r, 2]), self.built[child][0][r])
        return robot.moved(robot.nominal["cubes"][r], r) + error

    def leds(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, N_led, 3) the child's true LEDs in W."""
        robot = self.robots[child]
        error = np.einsum("tij,tkj->tki", rot_z(robot.true[r, 2]), self.built[child][1][r])
        return robot.moved(robot.nominal["leds"][r], r) + error

    def shots(self, child: str, r: Rows) -> NDArray[np.float64]:
        """(R, 3, 3) levelled, rounded polar shots at the child's three cubes."""
        centre, orientation = self.instrument(r)
        # In the instrument's (tilted) frame: R^T (p - c).
        local = np.einsum("tji,tkj->tki", orientation, self.cubes(child, r) - centre[:, None])
        # The instrument's tilt is the nominal station's (a turn about z leaves it).
        tilt = self.robots[self.plan.parent].nominal["tilt"][r]
        normals = self.draws.take(3, 3, rows=picked(r))  # the shots' noise, then the readings
        tilt_normals = self.draws.take(3, 2, rows=picked(r))
        polar, _ = shots_from_normals(
            local, tilt[:, None, :], self.spec, self.inclinometer, normals, tilt_normals
        )
        return polar
