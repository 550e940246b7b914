"""The parent's stations along a route: a travel in equal CPS legs."""

from __future__ import annotations

import math

from twin.campaign.plan.route import RoutePath


def leg_goals(path: RoutePath, s_from: float, s_to: float, step: float) -> list[float]:
    """Arc lengths of the parent's stations from ``s_from`` to ``s_to`` in equal legs of at
    most ``step`` m (the last is ``s_to``)."""
    n = max(1, math.ceil(abs(s_to - s_from) / step - 1e-9))
    return [s_from + (s_to - s_from) * (k + 1) / n for k in range(n)]
