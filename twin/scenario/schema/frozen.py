"""The base of every scenario model, and the names they share.

Units are SI (metres, seconds) except where a field's name says otherwise (``*_deg`` in
degrees, ``*_arcmin`` in arc-minutes, pixels for camera intrinsics). Positions are in the
world frame W: the parent's instrument frame at its first station, z up. The floor lies at
``space.floor_z`` (by default minus the instrument's height above the floor).

The models check each value on their own (types, ranges, lengths); cross-checks between
sections (a camera inside the space, a route clear of obstacles, a station that sees its
camera's view) live in :mod:`twin.scenario.cross_checks`.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Name = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=40)]


class Frozen(BaseModel):
    """Base of every scenario model: immutable, unknown keys rejected, no type coercion,
    no NaN or infinity."""

    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)
