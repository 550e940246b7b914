"""Recovery of a CPS leg that failed: back off to a place measured before, and plan the leg
again, shorter.

A leg fails when the standing parent cannot measure a child at its stop (turned, and
driven there again: :meth:`twin.campaign.travel.Travel.place_child_turning`), or when the
parent cannot fix its pose from the children after it drove (stepped aside too:
:mod:`twin.campaign.parent_fix`). Noise on the drives can leave a robot where a prism is
hidden, out of the instrument's range, or in line with the other child; a shorter leg
keeps the group where the plan saw it.

- A child the parent cannot measure at its stop first drives back to its last stand, is
  measured there, and drives to its stop again (:meth:`LegRecovery.drive_again`, event
  ``child_drove_again``). That failing, the leg is recovered:
- the child drives back the way it came (the route abreast of its stop, the route's
  corners, its last stand, where the parent measured it from this station, then a place
  beside the stand, then places on the straight line from the stand to the stop),
  measured wherever each drive ended until the parent finds it, and is placed there
  (event ``child_backed_off``).
- A parent that cannot fix its pose drives back along its move to where it last fixed it
  (the children, measured from there, show to it) and fixes it there (event
  ``parent_backed_off``).

Either raises :class:`LegRecovered`: the campaign asks its strategy for the leg again
(:class:`twin.campaign.strategy.NextLeg` with ``failed``), which plans it shorter. The
recoveries in a row are bounded (:attr:`twin.campaign.bounds.CampaignBounds.recoveries`):
reaching the bound ends the campaign with ``no_progress``. Where no back-off works the
campaign is aborted, naming the place.
"""

from __future__ import annotations

import math
from typing import NoReturn

import numpy as np
from numpy.typing import NDArray

from twin.campaign.aborted import CampaignAborted
from twin.campaign.parent_fix import ParentFix
from twin.campaign.strategy import Leg, Move
from twin.localization.observation import ChildObservation
from twin.localization.pose import ParentPose

BACK_OFF_APART = 0.1
"""Places of a child's way back closer than this, m, are one place."""

BACK_OFF_FRACTIONS = (0.25, 0.5)
"""Places tried last, as fractions of the straight line from a child's stand to its stop."""


class LegRecovered(Exception):
    """A leg failed and the group stands where the parent can measure it again: the
    campaign plans the leg again, shorter.

    Attributes:
        kind: the recovery's event (``child_backed_off``, ``parent_backed_off``).
    """

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


def _at(xy: NDArray[np.float64]) -> str:
    return f"({xy[0]:.2f}, {xy[1]:.2f}) m"


def _way_back(move: Move, stand: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """The places a child passed on ``move`` from its ``stand``, from its stop back: the
    route abreast of the stop, the route's corners, where it joined the route, the stand
    (each once)."""
    way: list[NDArray[np.float64]] = []
    for point in [move.on_route, *reversed(move.corners), move.entry, stand]:
        p = np.asarray(point, dtype=float)
        if not way or np.linalg.norm(p - way[-1]) > BACK_OFF_APART:
            way.append(p)
    return way


class LegRecovery(ParentFix):
    """The recovery of a failed leg, for :class:`twin.campaign.travel.Travel` (which
    provides the drives, the measurements and the placing of a child)."""

    recoveries: int
    max_recoveries: int | None

    def _count_recovery(self) -> None:
        """One more recovery in a row.

        Raises:
            NoProgress: the recoveries in a row reached their bound.
        """
        bound = self.max_recoveries
        if bound is not None and self.recoveries >= bound:
            raise self.no_progress("recoveries of a leg in a row", self.recoveries, bound)
        self.recoveries += 1

    def drive_again(self, move: Move) -> ChildObservation | None:
        """A child the parent cannot measure where it stopped, turned or not, may have
        stopped off its goal (its odometry carries its heading's error) behind what the
        plan kept clear: it drives back to where it stood at the parent's last fix (which
        the parent saw from where it stands), is measured there and its odometry
        corrected, and drives to its stop again. Its observation there, or None."""
        child = move.robot
        if child not in self.placed:
            return None
        base = self.rig.children[child]
        stand = self.cps.child_position(child)[0][:2]
        self.journal.event("child_drove_again", "back to its last stand and again", child)
        heading = math.atan2(*(stand - self.child_pose(child)[:2])[::-1])
        if not self._drive(base, stand, self._showing(stand, heading)).reached:
            return None
        seen = self.measure(child)
        if seen is None:
            return None
        self._correct_child_pose(child, seen, self.cps.parent)
        if not self.drive_along(base, move):
            return None
        return self.place_child_turning(child)

    def recover_child(self, move: Move) -> NoReturn:
        """The standing parent cannot measure ``move``'s child at its stop: it backs off the
        way it came (see the module), measured wherever each drive ends until the parent
        finds it, and is placed there.

        Raises:
            LegRecovered: the child was placed where it backed off to.
            CampaignAborted: it was measured nowhere (the message names its stop).
            NoProgress: the recoveries in a row reached their bound.
        """
        child = move.robot
        stop = np.asarray(move.stop.xy, dtype=float)
        if child not in self.placed:
            raise CampaignAborted(
                f"the parent cannot measure {child} at its stop {_at(stop)}, and it has no "
                "stand measured before to back off to"
            )
        self._count_recovery()
        base = self.rig.children[child]
        stand = self.cps.child_position(child)[0][:2]
        way = _way_back(move, stand)
        # From the place of the way nearest where the child is (its stop; its stand, if it
        # stopped there on its drive again).
        here = self.child_pose(child)[:2]
        way = way[int(np.argmin([np.linalg.norm(p - here) for p in way])) :]
        # A stand the child's estimate puts against a wall (a doorway's side) is refused: a
        # place a quarter of the way from it to where the child came from, after it.
        way.append(stand + 0.25 * ((way[-2] if len(way) > 1 else stop) - stand))
        # Then places on the straight line from the stand to the stop (a turn's inside).
        way += [stand + f * (stop - stand) for f in BACK_OFF_FRACTIONS]
        for k, place in enumerate(way):
            heading = math.atan2(*(place - self.child_pose(child)[:2])[::-1])
            # Measured where it stopped, got there or not (short of a refused goal).
            self._drive(base, place, self._showing(place, heading))
            last = k >= len(way) - 2 - len(BACK_OFF_FRACTIONS)
            placed = self.place_child_turning(child) if last else self.place_child(child)
            if placed is not None:
                message = (
                    f"the parent cannot measure it at its stop {_at(stop)}: backed off to "
                    f"{_at(place)}, the leg planned again shorter"
                )
                self.journal.event(
                    "child_backed_off", message, child, x=float(place[0]), y=float(place[1])
                )
                raise LegRecovered("child_backed_off", message)
        raise CampaignAborted(
            f"the parent cannot measure {child} at its stop {_at(stop)}, nor on its way back "
            f"to its last stand {_at(stand)}"
        )

    def recover_parent(self, leg: Leg, before: ParentPose) -> NoReturn:
        """The parent cannot fix its pose after ``leg``: it drives back along its move to
        ``before`` (its pose at its last fix) and fixes it there.

        Raises:
            LegRecovered: the parent fixed its pose where it backed off to.
            CampaignAborted: it could not fix it there either (the message names both places).
            NoProgress: the recoveries in a row reached their bound.
        """
        stop = np.asarray(leg.parent.stop.xy, dtype=float)
        back = np.asarray(before.translation[:2], dtype=float)
        self._count_recovery()
        parent = self.rig.parent
        for corner in reversed(leg.parent.corners):
            if not self._go(parent, np.asarray(corner, dtype=float)).reached:
                break
        self._go(parent, back, before.yaw)
        if self.fix_parent():
            message = (
                f"no fix at {_at(stop)}: back at its last fix {_at(back)}, the leg planned again "
                "shorter"
            )
            self.journal.event(
                "parent_backed_off", message, parent.name, x=float(back[0]), y=float(back[1])
            )
            raise LegRecovered("parent_backed_off", message)
        raise CampaignAborted(
            f"the parent could not fix its pose from the children at {_at(stop)}, nor back at its "
            f"last fix {_at(back)} (if they may move while the parent drives, say how far in "
            "campaign.child_creep_m)"
        )
