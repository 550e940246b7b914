"""``[campaign]`` and ``[[control_points]]``: how the calibration campaign runs and the
points the parent measures on its way."""

from __future__ import annotations

import typing
from typing import Annotated, Literal

from pydantic import Field, field_validator
from pydantic_core import PydanticCustomError

from twin.scenario.limits import MAX_CAMERAS, Point3
from twin.scenario.schema.frozen import Frozen, Name

StrategyName = Literal["planned", "paper"]
"""The strategies the campaign knows by name; :data:`twin.campaign.strategies.STRATEGIES`
makes each. A scenario that names another is refused as it loads."""


class FormationSettings(Frozen):
    """Where the children stop relative to the parent's next station during CPS travel.

    Both children stand ahead of the station along the route, the nearer ``near_gap`` and
    the farther ``near_gap + spacing`` metres on, offset sideways by ``lateral`` (the nearer
    to one side, the farther to the other) so that neither hides the other's prisms. Where
    a position is not free, the planner tries smaller and mirrored offsets.

    Attributes:
        step: the parent's advance per CPS step, m.
        near_gap, spacing, lateral: m.
    """

    step: Annotated[float, Field(gt=0.5, le=50.0)] = 5.0
    near_gap: Annotated[float, Field(gt=1.3, le=50.0)] = 2.5
    spacing: Annotated[float, Field(gt=0.5, le=50.0)] = 2.5
    lateral: Annotated[float, Field(ge=0.0, le=5.0)] = 0.7


class CampaignSettings(Frozen):
    """How the calibration campaign runs (paper Section IV).

    Attributes:
        reference_cameras: cameras for which reference data sets are taken from the
            parent's first station; None: every camera whose floor view the first station
            sees (at least ``calibration.min_visible_fraction`` of it).
        reference_points: LED points in each reference data set (paper: 70).
        station_points: LED points gathered at each calibration station.
        min_points: fewest points a station must yield for the camera to be calibrated.
        formation: the children's places during CPS travel.
        led_sequence: LED switching sequence, ``binary`` (6 frames for 4 LEDs) or
            ``one_at_a_time`` (6 frames).
        lock_retries: further aims after a lost prism lock before a shot is given up.
        pixel_size_mm: the sensor's pixel pitch, for kappa1 in the paper's 1/mm^2: 0.5 um
            (the smallest pixels made are about 0.56 um) to 0.1 mm.
        strategy: the campaign's decisions (visits, legs, data stops) by name:
            ``planned`` (the default: the paper's visits and legs, each camera's data stops
            chosen for accuracy) or ``paper`` (the paper's, its stops too). ``twin run
            --strategy`` overrides it. Any other name is refused as the scenario loads.
        child_creep_m: how far the campaign allows a standing child to move on each
            horizontal axis while the parent drives, m (standard deviation): CPS adds it to
            the children's positions before each of the parent's fixes, in its estimate,
            its consistency test and its covariance. What the twin simulates is
            ``noise.child_creep_m``; set this to what you know of your robots. Default 0.
        data_stops: where a child stops in a camera's view for its data. ``all_leds`` (the
            default): only where all its LEDs show, spread over the view
            (:func:`twin.campaign.plan.view_stops.view_stops`). ``accuracy``: wherever at
            least one LED shows, chosen greedily to lower the predicted covariance of the
            calibrated camera's position (:mod:`twin.campaign.plan.accurate_stops`); a stop
            where only some LEDs are found then gives a point with those (the others'
            failures still journaled). Every fidelity supports both (the batch replays
            each stop with the LEDs its noise-free plan found).
        progress_slack: how many times what a campaign that progresses needs each of its
            loops may take (the legs of a travel, the travels, the stops of a data set, the
            drives) before it ends with the failure ``no_progress``; the bounds are
            :func:`twin.campaign.bounds.campaign_bounds`. From 1 to 100; default 2.
    """

    reference_cameras: tuple[Name, ...] | None = Field(default=None, max_length=MAX_CAMERAS)
    reference_points: Annotated[int, Field(ge=8, le=1000)] = 70
    station_points: Annotated[int, Field(ge=8, le=1000)] = 70
    min_points: Annotated[int, Field(ge=8, le=1000)] = 24
    formation: FormationSettings = FormationSettings()
    led_sequence: Literal["binary", "one_at_a_time"] = "binary"
    lock_retries: Annotated[int, Field(ge=0, le=10)] = 3
    pixel_size_mm: Annotated[float, Field(ge=0.0005, le=0.1)] = 0.015
    strategy: StrategyName = "planned"
    child_creep_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0
    data_stops: Literal["all_leds", "accuracy"] = "all_leds"
    progress_slack: Annotated[float, Field(ge=1.0, le=100.0)] = 2.0

    @field_validator("strategy", mode="before")
    @classmethod
    def _known_strategy(cls, v: object) -> object:
        known = typing.get_args(StrategyName)
        if isinstance(v, str) and v not in known:
            raise PydanticCustomError(
                "unknown_strategy",
                "unknown strategy",
                {"expected": f"a strategy the campaign knows: {', '.join(sorted(known))}"},
            )
        return v


class ControlPoint(Frozen):
    """A point the parent measures whenever it stands near it: a prism left on a pole
    (at the start, say) or a surveyed mark. Measured again after a loop, it closes the loop
    in the global adjustment (:mod:`twin.localization.adjustment`).

    Attributes:
        name: identifier.
        position: (x, y, z) of the prism's centre in W, m (where the twin puts it; the
            campaign aims there until it has measured the point).
        surveyed: the position is known (surveyed into W): the adjustment holds it fixed.
            Otherwise only the campaign's own measurements place it.
        sight_radius_m: the parent measures the point from every station within this
            horizontal distance of it, m.
    """

    name: Name
    position: Point3
    surveyed: bool = False
    sight_radius_m: Annotated[float, Field(gt=0.0, le=100.0)] = 8.0
