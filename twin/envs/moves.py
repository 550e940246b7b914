"""The moves an agent chooses from in :class:`twin.envs.CpsCampaignEnv`: one ``Discrete``
action whose values are laid out by :class:`MoveLayout`.

At a CPS leg (the group travels towards a station):

- ``leg(formation, step)``: the children take their places in a :data:`FORMATIONS` entry,
  the parent advances ``step`` times the scenario's ``campaign.formation.step`` along the
  route (the travel is cut into equal legs of at most that length; the last leg ends at the
  station).

Between travels (the group stands at a station):

- ``calibrate``: take a data set for the camera whose station the parent stands at, and
  calibrate it;
- ``go_to(k)``: travel to station ``k`` (the site's calibration stations, in the order of
  the scenario's visits, each a camera's; without calibrating on arrival: the next
  decision is taken there);
- ``return_start``: travel back to the first station (to close the loop);
- ``end``: the campaign ends.

At a leg with no room for any formation, ``end`` is the one move allowed: the campaign
aborts, as the paper's strategy does where it finds no formation.

An action is a Python int or a numpy integer (a scalar or a 0-d array) in ``0 .. size - 1``
(:meth:`MoveLayout.check`); anything else (a bool, a float, a value outside the space) is
refused with ``ValueError`` wherever an action is taken.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from twin.scenario.schema import FormationSettings

__all__ = [
    "FORMATIONS",
    "STEP_FACTORS",
    "MoveLayout",
    "formation_settings",
]


def _in_line(form: FormationSettings) -> FormationSettings:
    return form


def _side_by_side(form: FormationSettings) -> FormationSettings:
    # Both children at the near gap, one to each side (the planner narrows the offsets
    # where the space is narrow); no spacing along the route.
    return form.model_copy(update={"spacing": 0.0, "lateral": max(1.0, form.lateral)})


def _staggered(form: FormationSettings) -> FormationSettings:
    return form.model_copy(update={"lateral": 2.0 * form.lateral})


def _long(form: FormationSettings) -> FormationSettings:
    return form.model_copy(update={"spacing": 2.0 * form.spacing})


FORMATIONS: Mapping[str, Callable[[FormationSettings], FormationSettings]] = {
    "in_line": _in_line,
    "side_by_side": _side_by_side,
    "staggered": _staggered,
    "long": _long,
}
"""Where the children stand for a leg, from the scenario's ``campaign.formation``:

- ``in_line``: the scenario's formation (the paper's): in line ahead of the parent's next
  station, ``near_gap`` and ``near_gap + spacing`` on, staggered by +/- ``lateral``;
- ``side_by_side``: both ``near_gap`` ahead, at +/- max(1 m, ``lateral``) across;
- ``staggered``: in line with twice the sideways offset;
- ``long``: in line with twice the spacing (a longer base for the parent's heading).
"""

STEP_FACTORS = (0.5, 1.0, 1.5)
"""The leg lengths an agent chooses from, in units of ``campaign.formation.step``."""


def formation_settings(name: str, form: FormationSettings) -> FormationSettings:
    """The settings of formation ``name`` built from the scenario's ``form``.

    Raises:
        ValueError: no formation has that name.
    """
    try:
        return FORMATIONS[name](form)
    except KeyError:
        raise ValueError(
            f"unknown formation {name!r}; formations: {', '.join(FORMATIONS)}"
        ) from None


@dataclass(frozen=True)
class MoveLayout:
    """Which action value is which move.

    Attributes:
        formations: the formations' names, in action order.
        step_factors: the leg lengths, in units of the scenario's step.
        max_stations: stations an action can name (a site's are padded to it).
    """

    formations: tuple[str, ...] = tuple(FORMATIONS)
    step_factors: tuple[float, ...] = STEP_FACTORS
    max_stations: int = 12

    def __post_init__(self) -> None:
        for name in self.formations:
            if name not in FORMATIONS:
                raise ValueError(f"unknown formation {name!r}; formations: {', '.join(FORMATIONS)}")
        if not self.formations or not self.step_factors:
            raise ValueError("a layout needs at least one formation and one step factor")
        if any(not (0.05 <= f <= 5.0) for f in self.step_factors):
            raise ValueError(f"step factors must lie in [0.05, 5], got {self.step_factors}")
        if self.max_stations < 1:
            raise ValueError(f"max_stations must be >= 1, got {self.max_stations}")

    @property
    def legs(self) -> int:
        """Values that are legs (formation x step)."""
        return len(self.formations) * len(self.step_factors)

    @property
    def calibrate(self) -> int:
        """The value of ``calibrate``."""
        return self.legs

    def go_to(self, k: int) -> int:
        """The value of ``go_to(k)``, station ``k`` in the site's order."""
        return self.legs + 1 + k

    @property
    def return_start(self) -> int:
        """The value of ``return_start``."""
        return self.legs + 1 + self.max_stations

    @property
    def end(self) -> int:
        """The value of ``end``."""
        return self.legs + 2 + self.max_stations

    @property
    def size(self) -> int:
        """Number of action values."""
        return self.legs + 3 + self.max_stations

    def check(self, action: object) -> int:
        """The move value of ``action``, an element of the action space ``Discrete(size)``.

        Args:
            action: a Python int, a numpy integer scalar or a 0-d integer array.

        Returns:
            The action as a Python int, in ``0 .. size - 1``.

        Raises:
            ValueError: ``action`` is of another type (a bool, a float, a longer array...)
                or outside the space.
        """
        if isinstance(action, np.ndarray):
            integer = action.ndim == 0 and action.dtype.kind in "iu"
        else:  # a bool is an int to Python, not to the space
            integer = isinstance(action, (int, np.integer)) and not isinstance(action, bool)
        if integer and 0 <= int(action) < self.size:  # type: ignore[call-overload]
            return int(action)  # type: ignore[call-overload]
        what = "outside" if integer else f"not an integer ({type(action).__name__}), so not in"
        raise ValueError(
            f"action {action!r} is {what} the action space Discrete({self.size}): expected an "
            f"int in 0 .. {self.size - 1}"
        )

    def leg(self, formation: str, step_factor: float) -> int:
        """The value of a leg in ``formation`` with the step factor nearest ``step_factor``."""
        f = self.formations.index(formation)
        s = int(np.argmin(np.abs(np.asarray(self.step_factors) - step_factor)))
        return f * len(self.step_factors) + s

    def leg_of(self, action: int) -> tuple[str, float]:
        """(formation, step factor) of a leg value."""
        if not 0 <= action < self.legs:
            raise ValueError(f"action {action} is not a leg (legs are 0 .. {self.legs - 1})")
        f, s = divmod(action, len(self.step_factors))
        return self.formations[f], self.step_factors[s]

    def describe(self, action: int) -> str:
        """The move's name, e.g. ``leg(in_line, 1.0)`` or ``go_to(2)``.

        Raises:
            ValueError: ``action`` is not in the action space (see :meth:`check`).
        """
        action = self.check(action)
        if 0 <= action < self.legs:
            formation, factor = self.leg_of(action)
            return f"leg({formation}, {factor:g})"
        if action == self.calibrate:
            return "calibrate"
        if self.legs < action < self.return_start:
            return f"go_to({action - self.legs - 1})"
        if action == self.return_start:
            return "return_start"
        assert action == self.end
        return "end"

    def fallback(self, action: int, mask: NDArray[np.bool_]) -> int:
        """The allowed move that replaces a forbidden ``action``.

        A leg is replaced by the allowed leg nearest in the layout: the same formation with
        the nearest shorter (then longer) step first, then the other formations in order.
        Any other move, or a leg where no leg is allowed, by the first allowed of
        ``calibrate``, ``go_to`` in station order, ``return_start`` and ``end``.

        Raises:
            ValueError: ``action`` is not in the action space (see :meth:`check`), or
                nothing is allowed.
        """
        action = self.check(action)
        allowed = np.flatnonzero(mask)
        if not len(allowed):
            raise ValueError("no move is allowed")
        legs = allowed[allowed < self.legs]
        if 0 <= action < self.legs and len(legs):
            n_steps = len(self.step_factors)
            f, s = divmod(action, n_steps)
            order = [f] + [g for g in range(len(self.formations)) if g != f]
            for g in order:
                # Shorter steps first (by distance in the list), then longer ones.
                for t in sorted(range(n_steps), key=lambda t: (abs(t - s), t > s)):
                    value = g * n_steps + t
                    if mask[value]:
                        return value
        return int(allowed[allowed >= self.legs][0] if (allowed >= self.legs).any() else legs[0])
