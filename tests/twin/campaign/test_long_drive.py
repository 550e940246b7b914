"""A child sent far on its wheel odometry is tracked by the standing parent: a heading a
couple of degrees off carries it metres sideways over a long drive, and measuring it on the
way brings it to its goal."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import twin.sim  # noqa: F401  (headless rendering is configured before MuJoCo loads)
from twin.campaign import Campaign
from twin.campaign.drives import LONG_DRIVE_M, TRACK_STEP_M
from twin.scenario import load_scenario
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

ROOT = Path(__file__).resolve().parents[3]
CORRIDOR = ROOT / "scenarios" / "corridor.toml"
SMOKE = ROOT / "scenarios" / "smoke.toml"

HEADING_ERROR = math.radians(2.0)
"""How far the child's belief of its heading is off the truth, rad."""


class _Records:
    def __init__(self) -> None:
        self.events: list[str] = []

    def record(self, topic: str, record: object, timestamp: float) -> None:
        if topic == "/campaign/event":
            self.events.append(record.kind)  # type: ignore[attr-defined]


def _drive_far(tracked: bool) -> tuple[float, list[str]]:
    """Send child1, its heading belief off by :data:`HEADING_ERROR`, 40 m down the
    corridor; (its true distance from the goal, m; the campaign's events)."""
    sc = load_scenario(CORRIDOR)
    sim = build_sim_rig(build_world(sc), "geometric", seed=3)
    records = _Records()
    campaign = Campaign(sim.rig, sc, records)
    child = sim.rig.children["child1"]
    x, y, yaw = child.odometry().pose
    child.set_pose(x, y, yaw + HEADING_ERROR)  # the truth stays where it was
    goal = np.array([x + 40.0, y])
    assert np.linalg.norm(goal - [x, y]) > LONG_DRIVE_M
    if tracked:
        assert campaign.travel._drive(child, goal).reached
    else:
        assert child.drive_to(goal).reached
    truth = sim.frame.pose(sim.world.robot_pose("child1"))
    sim.close()
    return float(np.linalg.norm(truth[:2] - goal)), records.events


def test_an_untracked_long_drive_ends_far_off_its_goal():
    off, _ = _drive_far(tracked=False)
    # 40 m at 2 degrees: 1.4 m sideways (the stopping error, 0.02 m, aside).
    assert off == pytest.approx(40.0 * HEADING_ERROR, abs=0.1)


def test_a_tracked_long_drive_ends_at_its_goal():
    off, events = _drive_far(tracked=True)
    pieces = math.ceil(40.0 / TRACK_STEP_M)
    assert events.count("child_tracked") == pieces - 1
    # After the last measurement, TRACK_STEP_M m at the heading the measured marker pose
    # gave (a fraction of a degree) and one stopping error (0.02 m per axis).
    assert off < 0.15


def test_a_child_not_measured_at_its_stop_drives_back_and_again(monkeypatch):
    # The parent cannot measure the first child at its first stop of a leg, turned or not
    # (a prism hidden behind what the plan kept clear): the child drives back to its last
    # stand, is measured there, and drives to its stop again.
    sc = load_scenario(SMOKE)
    sim = build_sim_rig(build_world(sc), "geometric")
    records = _Records()
    campaign = Campaign(sim.rig, sc, records)
    travel = campaign.travel
    placing, driving, executing = travel.place_child_turning, travel._drive, travel.execute
    refused: list[tuple[str, np.ndarray]] = []  # the child, its stand at the last fix
    goals: list[tuple[str, np.ndarray]] = []
    legs: list[object] = []

    def leg(planned):
        legs.append(planned)
        try:
            return executing(planned)
        finally:
            legs.pop()

    def hidden_once(child: str):
        if legs and not refused:
            refused.append((child, travel.cps.child_position(child)[0][:2].copy()))
            return None
        return placing(child)

    def drive(base, goal_xy, goal_yaw=None):
        goals.append((base.name, np.asarray(goal_xy, dtype=float).copy()))
        return driving(base, goal_xy, goal_yaw)

    monkeypatch.setattr(travel, "execute", leg)
    monkeypatch.setattr(travel, "place_child_turning", hidden_once)
    monkeypatch.setattr(travel, "_drive", drive)
    outcome = campaign.run()
    sim.close()
    assert refused, "the smoke run has no CPS leg"
    child, stand = refused[0]
    assert records.events.count("child_drove_again") == 1
    assert any(name == child and np.allclose(goal, stand) for name, goal in goals)
    assert outcome.failures["campaign_aborted"] == 0
    assert [c.points for c in outcome.calibrations] == [70]
