"""The strategies the campaign knows by name (``twin run --strategy NAME``, a scenario's
``campaign.strategy``)."""

from __future__ import annotations

from collections.abc import Callable

from twin.campaign.paper_strategy import PaperStrategy, PlannedStrategy
from twin.campaign.strategy import Strategy
from twin.scenario.schema import Scenario

STRATEGIES: dict[str, Callable[[], Strategy]] = {
    PaperStrategy.name: PaperStrategy,
    PlannedStrategy.name: PlannedStrategy,
}
"""Each strategy's maker, by name: the names of :data:`twin.scenario.schema.StrategyName`,
which a scenario's ``campaign.strategy`` is checked against as it loads."""

DEFAULT_STRATEGY = PlannedStrategy.name
"""The strategy of a scenario that names none."""


def strategy_named(name: str) -> Strategy:
    """A new instance of the strategy called ``name``.

    Raises:
        ValueError: no strategy has that name (the message lists those that do).
    """
    try:
        make = STRATEGIES[name]
    except KeyError:
        known = ", ".join(sorted(STRATEGIES))
        raise ValueError(f"unknown strategy {name!r}; strategies: {known}") from None
    return make()


def strategy_name(scenario: Scenario, name: str | None = None) -> str:
    """The name of the strategy a run uses: ``name``, else the scenario's
    ``campaign.strategy``; checked to be known, nothing built (a Monte-Carlo run's trials
    each build their own).

    Raises:
        ValueError: no strategy has that name; the message names where it came from.
    """
    chosen = name if name is not None else scenario.campaign.strategy
    if chosen not in STRATEGIES:
        where = "--strategy" if name is not None else "campaign.strategy"
        source = f" in {scenario.source}" if name is None and scenario.source else ""
        known = ", ".join(sorted(STRATEGIES))
        raise ValueError(f"{where}{source}: unknown strategy {chosen!r}; strategies: {known}")
    return chosen


def strategy_for(scenario: Scenario, strategy: Strategy | str | None = None) -> Strategy:
    """The strategy a run uses: ``strategy`` itself when it is already built (an entry point
    builds it once), else a new instance of the strategy it names, or of the scenario's
    ``campaign.strategy``.

    Raises:
        ValueError: no strategy has that name; the message names where it came from.
    """
    if isinstance(strategy, Strategy):
        return strategy
    return strategy_named(strategy_name(scenario, strategy))
