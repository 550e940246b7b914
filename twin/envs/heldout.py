"""The seeds a policy trains on and the held-out test sets it is evaluated on
(``twin strategies --test-set NAME``), in one place.

An episode is drawn from its reset seed: on random sites (``scenario="random"``) the site
itself (:mod:`twin.envs.sites`) and its noise, on a scenario file the noise. So a range of
reset seeds is a set of episodes, and two ranges that do not overlap share none:

- training resets with seeds of :data:`TRAINING_SEEDS` (``0 .. 10^9 - 1``): a vector is
  seeded with one of them (episode k with ``seed + k``), and the episodes after the first
  draw theirs from their environment's generator, never from a seed of a test set;
- every test set's seeds lie at :data:`TEST_SEEDS_START` (``10^9``) or above, each set in a
  range of its own.

A random site's own seed (the number in its name, ``hall_<seed>``) is drawn from the
episode's generator among 2^31 values; the episodes training draws from its generators can
meet a test site only by that draw, with a chance of about ``episodes x 200 / 2^31``
(0.01 for 100,000 training episodes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from twin.envs.scenario_paths import PACKAGE_SCENARIOS

if TYPE_CHECKING:
    from twin.scenario.schema import Scenario

__all__ = [
    "DEFAULT_TEST_SET",
    "TEST_SEEDS_START",
    "TEST_SETS",
    "TRAINING_SEEDS",
    "TestSet",
    "check_training_seed",
    "test_set",
]

TRAINING_SEEDS = range(0, 10**9)
"""The reset seeds training may use."""

TEST_SEEDS_START = 10**9
"""Every test set's seeds lie at or above this one: training never uses them."""


@dataclass(frozen=True)
class TestSet:
    """Held-out episodes: a site and the reset seeds of its episodes.

    Attributes:
        name: the name ``--test-set`` takes. scenario: ``"random"`` (a random site per
            episode, drawn from its seed) or the name of one of the project's
            scenarios (``scenarios/NAME.toml``). seeds: the episodes' reset seeds, in order.
        description: what it is for.
    """

    __test__ = False  # a test set of episodes, not one of pytest's

    name: str
    scenario: str
    seeds: range
    description: str

    @property
    def episodes(self) -> int:
        """How many episodes it has."""
        return len(self.seeds)

    def load(self) -> Scenario | None:
        """Its site: the project's scenario (``scenarios/NAME.toml``), or None for random
        sites."""
        if self.scenario == "random":
            return None
        from twin.scenario import load_scenario

        return load_scenario(PACKAGE_SCENARIOS / f"{self.scenario}.toml")


TEST_SETS: dict[str, TestSet] = {
    t.name: t
    for t in (
        TestSet(
            "random",
            "random",
            range(TEST_SEEDS_START, TEST_SEEDS_START + 200),
            "200 random corridors and halls that training never meets",
        ),
        TestSet(
            "random-quick",
            "random",
            range(TEST_SEEDS_START + 10_000, TEST_SEEDS_START + 10_020),
            "20 other random sites, for a quick look while training",
        ),
        TestSet(
            "hall",
            "paper_hall",
            range(TEST_SEEDS_START + 20_000, TEST_SEEDS_START + 20_100),
            "the paper's hall, 100 noise draws that training never uses",
        ),
        TestSet(
            "smoke",
            "smoke",
            range(TEST_SEEDS_START + 30_000, TEST_SEEDS_START + 30_003),
            "the smoke room, 3 episodes: checks a policy and the evaluation in seconds",
        ),
    )
}
"""The test sets by name (their seed ranges never overlap each other or training's)."""

DEFAULT_TEST_SET = "random"
"""The test set a learned policy is judged on."""


def test_set(name: str) -> TestSet:
    """The test set called ``name``.

    Raises:
        ValueError: no test set has that name (the message lists those that do).
    """
    try:
        return TEST_SETS[name]
    except KeyError:
        raise ValueError(f"unknown test set {name!r}; test sets: {', '.join(TEST_SETS)}") from None


test_set.__test__ = False  # type: ignore[attr-defined]


def check_training_seed(seed: int, episodes: int = 1) -> int:
    """``seed``, after checking that the reset seeds ``seed .. seed + episodes - 1`` lie in
    :data:`TRAINING_SEEDS`.

    Raises:
        ValueError: one of them does not (it would be one of a test set's or beyond).
    """
    last = seed + episodes - 1
    if seed not in TRAINING_SEEDS or last not in TRAINING_SEEDS:
        raise ValueError(
            f"training seeds {seed} .. {last}: expected seeds from {TRAINING_SEEDS.start} to "
            f"{TRAINING_SEEDS.stop - 1} (those from {TEST_SEEDS_START} on are the test sets')"
        )
    return seed
