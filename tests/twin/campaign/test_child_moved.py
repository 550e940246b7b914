"""A child pushed while the other drives is found by the parent's check shots and placed
again, instead of spoiling the parent's next fix (which could not tell which child moved)."""

import math
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from twin.campaign.procedure import Campaign
from twin.campaign.shooting import STILL_NOISE_FREE, moved_between
from twin.instruments.consistency import chi2_threshold
from twin.localization.observation import ChildObservation
from twin.report.reading import planned_visits
from twin.runner import run_scenario
from twin.scenario import load_scenario
from twin.sim.rig.base import GeometricBase

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


def test_a_child_pushed_while_the_other_drives_is_placed_again(tmp_path, monkeypatch):
    legs: list[list[str]] = []
    move = Campaign._move_children

    def recording_move(self, stops, direction):
        legs.append(self._children_in_order(direction))
        return move(self, stops, direction)

    drive = GeometricBase.drive_to
    pushed: list[str] = []

    def pushing_drive(self, goal_xy, goal_yaw=None):
        # On the third leg, while the second child drives, push the first (placed) one.
        if len(legs) == 3 and not pushed and self.name == legs[-1][1]:
            first = legs[-1][0]
            x, y, yaw = self.world.robot_pose(first)
            self.world.place(first, (x + PUSH[0], y + PUSH[1]), yaw + math.radians(PUSH_YAW_DEG))
            pushed.append(first)
        return drive(self, goal_xy, goal_yaw)

    monkeypatch.setattr(Campaign, "_move_children", recording_move)
    monkeypatch.setattr(GeometricBase, "drive_to", pushing_drive)
    results = run_scenario(HALL, tmp_path, fidelity="geometric", seed=2, report=False)
    assert pushed, "no third leg"
    assert results["failures"].get("child_moved", 0) >= 1
    assert results["failures"].get("inconsistent_children", 0) == 0
    planned = [key for key, _ in planned_visits(load_scenario(HALL))]
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == planned
