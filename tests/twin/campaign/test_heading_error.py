"""A parent whose odometry heading is far off after a turn in place (a skid-steered robot
whose wheels scrub, or one with a wheel on a ledge) still fixes its pose: the first child
it finds orients the aim at the next, and a child's shots that find the other's marker
are rejected."""

import math
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import chi2

from calib.rotation import rot_z, wrap_angle
from twin.campaign.shooting import MIN_ORIENTING_RANGE, oriented_on, same_marker
from twin.hal.wrappers import MobileBaseWrapper, wrapped
from twin.localization.pose import ParentPose
from twin.montecarlo.prediction import predictions_from_log
from twin.record import read_log
from twin.report.reading import planned_visits
from twin.run.runner import run_scenario
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
HALL = ROOT / "scenarios" / "paper_hall.toml"

HEADING_ERROR_DEG = 25.0
"""The parent's true heading after its turn at camera 3's station, less its belief: what
the render fidelity's skid-steered parent showed there, its wheels on a floor ledge."""


@given(
    yaw=st.floats(-math.pi, math.pi),
    error=st.floats(-1.2, 1.2),
    bearing=st.floats(-math.pi, math.pi),
    distance=st.floats(MIN_ORIENTING_RANGE + 0.5, 60.0),
    height=st.floats(-1.0, 1.0),
    offset=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
)
def test_orienting_on_a_child_recovers_the_heading(yaw, error, bearing, distance, height, offset):
    true = ParentPose(yaw, np.array([3.0, -2.0, 0.1]))
    level = np.array([distance * math.cos(bearing), distance * math.sin(bearing), height])
    child_world = true.level2world(level)
    # The guess: heading off by up to 70 deg, position off by up to 7 cm.
    guess = ParentPose(yaw + error, true.translation + np.array([*offset, 0.0]))
    fixed = oriented_on(guess, child_world, level)
    # What is left is the bearing error that the position error makes at this range.
    bound = math.asin(min(1.0, math.hypot(*offset) / (distance - math.hypot(*offset))))
    assert abs(wrap_angle(fixed.yaw - yaw)) <= bound + 1e-9
    assert np.array_equal(fixed.translation, guess.translation)


def test_a_near_child_does_not_orient():
    guess = ParentPose(0.3, np.zeros(3))
    near = np.array([0.5, 0.2, 0.0])
    assert oriented_on(guess, near, rot_z(0.5).T @ near) is guess


def test_one_marker_measured_twice_is_told_from_two_children():
    a = np.array([2.82, 0.26, 1.0])
    assert same_marker(a, a + np.array([0.01, -0.01, 0.0]))
    # Two children side by side: their masts stand at least a body's width apart.
    assert not same_marker(a, a + np.array([0.0, 0.5, 0.0]))


class ScrubbingParent(MobileBaseWrapper):
    """The parent's base: after a turn to face north (camera 3's station), its true heading
    is knocked off its belief, as a skid-steered robot's scrubbing wheels do."""

    def __init__(self, inner, sim) -> None:
        super().__init__(inner)
        self.sim = sim
        self.turned: list[float] = []

    def drive_to(self, goal_xy, goal_yaw=None):
        result = self.inner.drive_to(goal_xy, goal_yaw)
        if goal_yaw is not None and abs(goal_yaw - math.pi / 2) < 0.1:
            world = self.sim.world
            x, y, yaw = world.robot_pose(self.name)
            world.place(self.name, (x, y), yaw + math.radians(HEADING_ERROR_DEG))
            self.turned.append(result.timestamp)
        return result


def test_a_parent_turned_far_off_its_belief_still_fixes_its_pose(tmp_path):
    parents: list[ScrubbingParent] = []

    def scrub_the_parent(sim):
        parents.append(ScrubbingParent(sim.rig.parent, sim))
        return wrapped(sim.rig, base=lambda base: parents[0] if base is sim.rig.parent else base)

    results = run_scenario(
        HALL,
        tmp_path,
        fidelity="geometric",
        seed=3,
        report=False,
        strategy="paper",
        adapt_rig=scrub_the_parent,
    )
    assert parents[0].turned, "the parent never turned at camera 3's station"
    assert results["complete"]
    planned = [key for key, _ in planned_visits(load_scenario(HALL))]
    assert [(c["camera"], c["visit"]) for c in results["calibrations"]] == planned
    assert "campaign_aborted" not in results["failures"]
    # The parent's final error stays what CPS makes it over 85 m: its NEES against the
    # propagated covariance within the two-sided 1e-4 quantiles of chi-square with 3
    # degrees of freedom (the hall's mean NEES over 80 seeds: 3.06).
    _, final = predictions_from_log(read_log(tmp_path / "log.mcap").messages)
    nees = final.error_m @ np.linalg.solve(final.covariance_m2, final.error_m)
    assert chi2.ppf(5e-5, 3) < nees < chi2.isf(5e-5, 3), nees
