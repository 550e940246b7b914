"""A leg the agent chose that failed (the group backed off to where it started): the next
choice is among shorter legs, as the campaign's own strategy plans the leg shorter."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import twin.sim  # noqa: F401  (headless rendering)
from twin.campaign.strategy import Leg, NextLeg
from twin.envs.leg_choices import shorter_than
from twin.envs.live_campaign import LEG, LiveCampaign
from twin.envs.moves import MoveLayout
from twin.scenario import load_scenario

HALL = Path(__file__).resolve().parents[3] / "scenarios" / "paper_hall.toml"


def test_only_legs_that_end_nearer_than_the_failed_one_are_shorter():
    leg = Leg.__new__(Leg)  # the leg itself is not looked at
    options = [(leg, 4.0), None, (leg, 7.0), (leg, 10.0), (leg, -1.0)]
    # From s = 2 m, a leg to 7 m failed: those ending within 5 m of 2 m are shorter.
    assert shorter_than(options, 2.0, 7.0) == [True, False, False, False, True]
    # Going back along the route the same.
    assert shorter_than(options, 12.0, 7.0) == [False, False, False, True, False]


def test_after_a_failed_leg_the_agent_may_take_only_shorter_ones():
    live = LiveCampaign(load_scenario(HALL), MoveLayout(), budget_m=1e4)
    for _ in range(200):  # to a leg choice among legs of several lengths
        if live.decision == LEG:
            s_now = live.strategy.position(live.view, live.session.question.goal)[0]
            ends = {int(a): live._legs[a][1] for a in np.flatnonzero(live.mask)}
            if len({round(abs(e - s_now), 6) for e in ends.values()}) > 1:
                break
        live.act(int(np.flatnonzero(live.mask)[0]))
    else:
        raise AssertionError("no choice between legs of different lengths")
    session = live.session
    question = session.question
    longest = max(ends, key=lambda a: abs(ends[a] - s_now))
    failed_leg = live._legs[longest][0]

    def fail(answer):
        # The leg failed: the group backed off to where it was, and is asked again.
        session.question = NextLeg(question.goal, failed_leg)
        return []

    session.answer = fail
    live.act(longest)
    assert live.decision == LEG
    again = np.flatnonzero(live.mask)
    assert len(again)
    assert longest not in again
    for a in again:
        assert abs(live._legs[a][1] - s_now) < abs(ends[longest] - s_now)
