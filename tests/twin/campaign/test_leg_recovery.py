"""A CPS leg that fails (a child the parent cannot measure at its stop, a parent that cannot
fix its pose where it stopped) is backed off from and planned again, shorter
(:mod:`twin.campaign.recovery`), instead of ending the campaign; a recovery that can never
succeed ends it with a named failure, not a loop.

The failures are scripted through the interface (:mod:`twin.hal.wrappers`): the instrument
finds no prism while a robot stands where the script hides it, as behind a wall.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from tests.twin.campaign.test_bounds import RETURN, _Log, _smoke
from twin.campaign import Campaign
from twin.campaign.bounds import recoveries_bound
from twin.campaign.records import EVENT, PARENT_FIX
from twin.hal.wrappers import MobileBaseWrapper, TotalStationWrapper, wrapped
from twin.instruments.errors import NoPrismInConeError
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

BEYOND = 3.0
"""The return's first leg takes the parent from its station (x = 0.5 m) to the route's far
end (x = 3.8 m); places beyond this x, m, are where the script hides things."""


BEHIND = 0.0
"""On the return's first leg the children go ahead to stops behind the start (x < 0 m),
from places beyond it; a place behind this x, m, is where the script hides a child."""


class Blind(TotalStationWrapper):
    """An instrument that finds no prism while ``hidden()`` says so."""

    def __init__(self, inner, hidden: Callable[[], bool]) -> None:
        super().__init__(inner)
        self.hidden = hidden

    def measure(self):
        if self.hidden():
            raise NoPrismInConeError("no prism within the search cone (scripted)")
        return self.inner.measure()


class Watched(MobileBaseWrapper):
    """A base that tells ``seen`` each goal it is sent to, before it drives."""

    def __init__(self, inner, seen: Callable[[str, np.ndarray], None]) -> None:
        super().__init__(inner)
        self.seen = seen

    def drive_to(self, goal_xy, goal_yaw=None):
        self.seen(self.name, np.asarray(goal_xy, dtype=float))
        return self.inner.drive_to(goal_xy, goal_yaw)


def _run(script) -> tuple[Campaign, _Log]:
    """The smoke room's visit and return, geometric, seed 1, with ``script`` (given the
    rig, and told the campaign's progress) scripting the instrument's blindness."""
    sc = _smoke(RETURN, return_to_start=True, reference_cameras=())
    sim = build_sim_rig(build_world(sc), "geometric", seed=1)
    log = _Log()
    try:
        rig = script(sim.rig)
        campaign = Campaign(rig, sc, log, getattr(script, "progress", None))
        campaign.run()
    finally:
        sim.close()
    return campaign, log


def _events(log: _Log, kind: str) -> list:
    return [r for t, r in log.records if t == EVENT and r.kind == kind]


def _fixes(log: _Log) -> list[np.ndarray]:
    return [np.asarray(r.translation[:2]) for t, r in log.records if t == PARENT_FIX]


class ParentHidden:
    """The children are hidden from the parent while it stands beyond :data:`BEYOND`, the
    first time it goes there (``once``) or every time."""

    def __init__(self, once: bool) -> None:
        self.once = once
        self.hidden = False
        self.times = 0

    def seen(self, robot: str, goal: np.ndarray) -> None:
        if robot != "parent":
            return
        beyond = goal[0] > BEYOND
        if beyond and not self.hidden:
            self.times += 1
        self.hidden = beyond and (not self.once or self.times == 1)

    def __call__(self, rig):
        return wrapped(
            rig,
            total_station=lambda ts: Blind(ts, lambda: self.hidden),
            base=lambda base: Watched(base, self.seen),
        )


def test_a_parent_that_cannot_fix_its_pose_backs_off_and_takes_a_shorter_leg():
    script = ParentHidden(once=True)
    campaign, log = _run(script)
    outcome = campaign.outcome
    assert script.times >= 1, "the parent never went beyond the hidden line"
    assert outcome.failures["campaign_aborted"] == 0
    assert outcome.failures["parent_fix_failed"] >= 1
    (backed,) = _events(log, "parent_backed_off")
    fixes = _fixes(log)
    # Back at its last fix (the station, x = 0.5 m) to the stopping noise (cm), then a
    # shorter leg than the failed one, which went to the far end (3.8 m).
    station = fixes[1]
    assert abs(station[0] - 0.5) < 0.05
    back = np.array([backed.details["x"], backed.details["y"]])
    assert np.linalg.norm(back - station) < 1e-9
    k = next(k for k in range(2, len(fixes)) if np.linalg.norm(fixes[k] - station) < 0.1)
    assert station[0] + 0.3 < fixes[k + 1][0] < BEYOND, fixes
    assert np.linalg.norm(fixes[-1]) < 0.1  # back at the start: the campaign completed
    assert len(outcome.calibrations) == 1


def test_a_leg_that_can_never_be_fixed_ends_with_no_progress_not_a_loop():
    script = ParentHidden(once=False)
    campaign, log = _run(script)
    outcome = campaign.outcome
    bound = campaign.bounds.recoveries
    assert bound == recoveries_bound(2.0) == 3
    backed = _events(log, "parent_backed_off")
    assert len(backed) >= bound  # shorter legs short of the line succeed, and reset the count
    (stuck,) = log.failures("no_progress")
    assert stuck.details["what"] == "recoveries of a leg in a row"
    assert stuck.details["count"] == stuck.details["bound"] == bound
    assert stuck.details["stage"] == "return"
    # Named where it stands: its last fix, where it backed off to (to the stopping noise).
    assert abs(stuck.details["x"] - backed[-1].details["x"]) < 0.05
    assert stuck.details["x"] < BEYOND
    assert outcome.failures["campaign_aborted"] == 1
    assert len(outcome.calibrations) == 1  # what was calibrated before is kept


class StopHidden:
    """The first stop a child drives to behind :data:`BEHIND` on the return hides its
    prisms: the instrument finds none while that child stands there (within 5 cm)."""

    def __init__(self) -> None:
        self.returning = False
        self.child: str | None = None
        self.stop: np.ndarray | None = None
        self.rig = None

    def hidden(self) -> bool:
        if self.child is None:
            return False
        here = self.rig.children[self.child].odometry().pose[:2]
        return bool(np.linalg.norm(here - self.stop) < 0.05)

    def progress(self, now) -> None:
        self.returning = now.stage == "return"

    def seen(self, robot: str, goal: np.ndarray) -> None:
        first = self.returning and robot.startswith("child") and self.child is None
        if first and goal[0] < BEHIND:
            self.child, self.stop = robot, goal.copy()

    def __call__(self, rig):
        self.rig = wrapped(
            rig,
            total_station=lambda ts: Blind(ts, self.hidden),
            base=lambda base: Watched(base, self.seen),
        )
        return self.rig


def test_a_child_the_parent_cannot_measure_backs_off_and_the_leg_is_planned_again():
    script = StopHidden()
    campaign, log = _run(script)
    outcome = campaign.outcome
    assert script.child is not None, "no child went behind the hidden line"
    assert outcome.failures["campaign_aborted"] == 0
    (drove_again,) = _events(log, "child_drove_again")
    (backed,) = _events(log, "child_backed_off")
    assert backed.robot == drove_again.robot == script.child
    assert f"at its stop ({script.stop[0]:.2f}, {script.stop[1]:.2f}) m" in backed.message
    assert np.linalg.norm(_fixes(log)[-1]) < 0.1  # back at the start: the campaign completed
    assert len(outcome.calibrations) == 1


def test_a_parent_that_cannot_fix_its_pose_anywhere_aborts_naming_both_places():
    class Everywhere(ParentHidden):
        def seen(self, robot, goal):  # hidden from the first time beyond on, wherever
            super().seen(robot, goal)
            self.hidden = self.hidden or self.times > 0

    _, log = _run(Everywhere(once=True))
    (aborted,) = log.failures("campaign_aborted")
    x, y = _fixes(log)[-1]  # the station, its last fix
    assert "the parent could not fix its pose from the children at (3." in aborted.message
    assert f"nor back at its last fix ({x:.2f}, {y:.2f}) m" in aborted.message
    assert not _events(log, "parent_backed_off")
    assert not log.failures("no_progress")


# -- a child's shots that found the other's marker ------------------------------------------------
def _travel_at_the_start():
    """The smoke room's campaign before it starts (geometric, seed 1) and its travel."""
    sc = _smoke(RETURN, return_to_start=True, reference_cameras=())
    sim = build_sim_rig(build_world(sc), "geometric", seed=1)
    log = _Log()
    return sim, Campaign(sim.rig, sc, log).travel, log


def _finds(travel, found: str):
    """``travel.measure`` for a parent whose shots at child1 find ``found``'s marker."""
    measure = travel.measure

    def measured(child, parent=None):
        obs = measure(found if child == "child1" else child, parent)
        return None if obs is None else dataclasses.replace(obs, child=child)

    return measured


def test_a_child_whose_shots_found_the_other_childs_marker_is_not_placed_there():
    sim, travel, log = _travel_at_the_start()
    try:
        assert travel.place_child("child2") is not None
        own = travel.measure
        travel.measure = _finds(travel, "child2")
        assert travel.place_child("child1") is None
        assert "child1" not in travel.placed
        (wrong,) = log.failures("wrong_child")
        assert (wrong.robot, wrong.message) == ("child1", "child1's shots found child2's marker")
        travel.measure = own  # its own marker: placed
        assert travel.place_child("child1") is not None
        assert travel.placed["child1"].child == "child1"
    finally:
        sim.close()


def test_a_check_shot_that_found_the_other_childs_marker_does_not_move_a_child():
    sim, travel, log = _travel_at_the_start()
    try:
        first, second = travel.place_child("child1"), travel.place_child("child2")
        assert first is not None
        assert second is not None
        travel.measure = _finds(travel, "child2")
        travel.check_stayed("child1", "child2")
        assert travel.placed["child1"] is first  # not placed again where child2 stands
        assert len(log.failures("wrong_child")) == 1
        assert not log.failures("child_moved")
    finally:
        sim.close()
