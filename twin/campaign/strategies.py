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
"""Each strategy's maker, by name."""

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


def strategy_for(scenario: Scenario, name: str | None = None) -> Strategy:
    """A new instance of the strategy ``name``, or of the scenario's ``campaign.strategy``.

    Raises:
        ValueError: no strategy has that name; the message names where it came from.
    """
    try:
        return strategy_named(name if name is not None else scenario.campaign.strategy)
    except ValueError as exc:
        where = "--strategy" if name is not None else "campaign.strategy"
        source = f" in {scenario.source}" if name is None and scenario.source else ""
        raise ValueError(f"{where}{source}: {exc}") from None
