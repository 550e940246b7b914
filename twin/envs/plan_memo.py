"""The noise-free campaigns of a site for every sequence of moves played so far
(:class:`PlanMemo`), kept per process for the episodes to share.

The campaign is deterministic given the moves, so a site's campaigns are kept as a tree of
the moves played: moves played before are read back, and only new ones run the campaign.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

from twin.batch.steps import BatchPlan, Step
from twin.envs.live_campaign import Decision
from twin.envs.moves import MoveLayout
from twin.scenario.schema import Scenario

MEMO_NODES = 200_000
"""Most decisions a site's memo keeps (beyond, new ones are computed and not kept)."""


MEMO_SITES = 8
"""Sites whose memos a process keeps (the least recently used is dropped)."""


@dataclass
class MemoNode:
    """A decision of the memo, and the moves taken from it so far."""

    state: Decision
    moves: dict[int, tuple[tuple[Step, ...], MemoNode]] = field(default_factory=dict)


class PlanMemo:
    """The noise-free campaign of one site for every sequence of moves played so far.

    The campaign is deterministic given the moves: a sequence played once is not computed
    again (its steps and decisions are read back), which makes a policy that repeats its
    moves, or a search that tries moves from the same decisions, cheap after the first
    episode. At most :data:`MEMO_NODES` decisions are kept.
    """

    def __init__(self, plan: BatchPlan, start: tuple[Step, ...], state: Decision) -> None:
        self.plan = plan
        self.start = start
        self.root = MemoNode(state)
        self.nodes = 1


_MEMOS: OrderedDict[tuple[str, MoveLayout, float], PlanMemo] = OrderedDict()


def memo_for(scenario: Scenario, layout: MoveLayout, budget_m: float) -> PlanMemo | None:
    """The process's memo of a site (None when there is none yet)."""
    key = (scenario.model_dump_json(), layout, budget_m)
    memo = _MEMOS.get(key)
    if memo is not None:
        _MEMOS.move_to_end(key)
    return memo


def keep_memo(scenario: Scenario, layout: MoveLayout, budget_m: float, memo: PlanMemo) -> None:
    _MEMOS[(scenario.model_dump_json(), layout, budget_m)] = memo
    while len(_MEMOS) > MEMO_SITES:
        _MEMOS.popitem(last=False)


def clear_memos() -> None:
    """Forget every site's memo (the next episodes compute their campaigns again)."""
    _MEMOS.clear()
