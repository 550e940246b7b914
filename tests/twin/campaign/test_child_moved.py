"""A child pushed while the other drives is found by the parent's check shots and placed
again, instead of spoiling the parent's next fix (which could not tell which child moved)."""

import math
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from twin.campaign.shooting import STILL_NOISE_FREE, moved_between
from twin.hal.wrappers import MobileBaseWrapper, wrapped
from twin.instruments.consistency import chi2_threshold
from twin.localization.observation import ChildObservation
from twin.report.reading import planned_visits
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
HALL = ROOT / "scenarios" / "paper_hall.toml"
RATE = 1e-4


def _obs(point, sigma):
    return ChildObservation("c", np.asarray(point, float), sigma**2 * np.eye(3))


@given(
    point=st.tuples(*[st.floats(-30.0, 30.0)] * 3),
    sigma=st.floats(1e-4, 5e-3),
    direction=st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda d: np.linalg.norm(d) > 0.1),
    k=st.floats(0.0, 3.0),
)
def test_a_shift_is_a_move_when_it_exceeds_the_noise_of_two_measurements(
    point, sigma, direction, k
):
    unit = np.asarray(direction) / np.linalg.norm(direction)
    # The difference of two measurements has variance 2 sigma^2 per axis; its chi-square
    # threshold on 3 degrees of freedom is a distance of sqrt(2 q) sigma.
    limit = math.sqrt(2.0 * chi2_threshold(3, RATE)) * sigma
    before = _obs(point, sigma)
    near = _obs(np.asarray(point) + 0.99 * limit * unit, sigma)
    far = _obs(np.asarray(point) + (1.01 + k) * limit * unit, sigma)
    assert not moved_between(before, near, RATE)
    assert moved_between(before, far, RATE)


def test_without_noise_any_shift_is_a_move():
    before = _obs([3.0, 1.0, 0.5], 0.0)
    assert not moved_between(before, before, None)
    assert moved_between(before, _obs([3.0, 1.0 + 10 * STILL_NOISE_FREE, 0.5], 0.0), None)


PUSH = np.array([0.02, -0.015])
"""How far the waiting child is pushed, m: what a child rolling off a floor patch's ledge
moved in the render fidelity before the robots held their wheels at rest."""
PUSH_YAW_DEG = 1.5


class Pusher:
    """Watches the bases' drives, as a wrapper device sees them: a CPS leg's children drive
    one after the other after the parent's last drive. On the third leg, while the second
    child drives, the first (already placed) is pushed in the world."""

    def __init__(self, sim) -> None:
        self.sim = sim
        self.legs = 0
        self.drivers: list[str] = []
        self.pushed: list[str] = []
        self.parent = sim.rig.parent.name

    def before_drive(self, robot: str) -> None:
        if robot == self.parent:
            self.drivers = []
            return
        if not self.drivers:
            self.legs += 1  # the first child's drive after the parent's: a new leg
        if robot not in self.drivers:
            self.drivers.append(robot)
        if self.legs == 3 and len(self.drivers) == 2 and not self.pushed:
            first = self.drivers[0]
            world = self.sim.world
            x, y, yaw = world.robot_pose(first)
            world.place(first, (x + PUSH[0], y + PUSH[1]), yaw + math.radians(PUSH_YAW_DEG))
            self.pushed.append(first)


class WatchedBase(MobileBaseWrapper):
    def __init__(self, inner, pusher: Pusher) -> None:
        super().__init__(inner)
        self.pusher = pusher

    def drive_to(self, goal_xy, goal_yaw=None):
        self.pusher.before_drive(self.name)
        return self.inner.drive_to(goal_xy, goal_yaw)


def test_a_child_pushed_while_the_other_drives_is_placed_again(tmp_path):
    pushers: list[Pusher] = []

    def push_on_the_third_leg(sim):
        pushers.append(Pusher(sim))
        return wrapped(sim.rig, base=lambda base: WatchedBase(base, pushers[0]))

    results = run_scenario(
        HALL,
        tmp_path,
        fidelity="geometric",
        seed=2,
        report=False,
        strategy="paper",
        adapt_rig=push_on_the_third_leg,
    )
    assert pushers[0].pushed, "no third leg"
    assert results["failures"].get("child_moved", 0) >= 1
    assert results["failures"].get("inconsistent_children", 0) == 0
    planned = [key for key, _ in planned_visits(load_scenario(HALL))]
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == planned


def test_without_the_push_no_child_moved(tmp_path):
    # The same run without the push: the check shots find nothing to place again.
    results = run_scenario(
        HALL, tmp_path, fidelity="geometric", seed=2, report=False, strategy="paper"
    )
    assert results["failures"].get("child_moved", 0) == 0


class _Events:
    def __init__(self) -> None:
        self.events: list[object] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        if topic == "/campaign/event":
            self.events.append(record)


def test_a_child_the_parent_cannot_measure_again_is_named_unchecked(monkeypatch):
    # The parent's check shot after the other child drove finds no prism (hidden behind the
    # child that drove, say): the check is not made, and the log says so.
    from twin.campaign import Campaign
    from twin.sim.rig import build_sim_rig
    from twin.sim.world import build_world

    sc = load_scenario(ROOT / "scenarios" / "smoke.toml")
    sim = build_sim_rig(build_world(sc), "geometric", seed=5)
    events = _Events()
    try:
        travel = Campaign(sim.rig, sc, events).travel
        travel.placed["child1"] = _obs([1.0, 0.5, 0.3], 1e-3)
        monkeypatch.setattr(travel, "measure", lambda child: None)
        travel.check_stayed("child1", "child2")
    finally:
        sim.close()
    (event,) = events.events
    assert event.kind == "child_unchecked"
    assert event.robot == "child1"
    assert "child1 not measured after child2 drove" in event.message
