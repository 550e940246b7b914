"""The goals a robot is driven to, recorded as the campaign sends them."""

from __future__ import annotations

import numpy as np


def recorded_goals(monkeypatch, base) -> list[np.ndarray]:
    """Record the (2,) goal of every ``drive_to`` of ``base`` (m) from now on, in order; the
    drives themselves go on as before."""
    goals: list[np.ndarray] = []
    driving = base.drive_to

    def drive(goal_xy, goal_yaw=None):
        goals.append(np.asarray(goal_xy, dtype=float).copy())
        return driving(goal_xy, goal_yaw)

    monkeypatch.setattr(base, "drive_to", drive)
    return goals
