"""``[noise]``: the total station, inclinometer, odometry, stopping and LED detection
noise."""

from __future__ import annotations

import math
import typing
from typing import Annotated

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from twin.instruments.total_station import InclinometerSpec, TotalStationSpec
from twin.scenario.robots import OdometrySpec
from twin.scenario.schema.frozen import Frozen
from twin.scenario.schema.spec_models import SpecConfig, model_from_dataclass

TotalStationConfig = model_from_dataclass(
    TotalStationSpec,
    "TotalStationConfig",
    """Total station noise (SI units); fields and defaults of TotalStationSpec.

    Ranges: the paper's instrument (Table I) has 2 mm + 2 ppm and 5 arc-seconds, and
    builders' instruments are a few times worse; noise up to 5 cm, 100 ppm and 1e-3 rad
    (206 arc-seconds), and resolutions up to 1 cm and 1e-3 rad, leave room for stress
    tests (the campaign already fails at a tenth of them). ``pointing_sigma`` (not in
    Table I, default 0) up to 2 cm: a corner cube a centimetre off its axis of aim.
    ``range_min`` is 0.1 m to 100 m;
    ``range_max`` at most 10 km, beyond the diagonal of the largest space (7.1 km; the
    paper's instrument reaches 2.2 km). ``aim_cone`` is 0.01 rad (0.6 deg, a narrow
    automatic aim) up to pi/2 rad.
    """,
    {
        "distance_sigma_const": Field(ge=0.0, le=0.05),
        "distance_sigma_ppm": Field(ge=0.0, le=100.0),
        "angle_sigma": Field(ge=0.0, le=1e-3),
        "distance_resolution": Field(ge=0.0, le=0.01),
        "angle_resolution": Field(ge=0.0, le=1e-3),
        "range_min": Field(ge=0.1, le=100.0),
        "range_max": Field(gt=0.0, le=10_000.0),
        "aim_cone": Field(ge=0.01, lt=0.5 * math.pi),
        "pointing_sigma": Field(ge=0.0, le=0.02),
    },
    __name__,
)


class _InclinometerChecks(SpecConfig):
    """Base of :data:`InclinometerConfig`: its noise must fit its working range."""

    @model_validator(mode="after")
    def _noise_within_working_range(self) -> typing.Self:
        sigma, working_range = self.sigma, self.working_range  # fields of the model below
        if sigma > 0.1 * working_range:
            raise PydanticCustomError(
                "noise_beyond_range",
                f"sigma = {sigma:g} rad is more than a tenth of working_range = "
                f"{working_range:g} rad: a level instrument would read out of its range",
                {"expected": f"sigma at most {0.1 * working_range:g} rad"},
            )
        return self


InclinometerConfig = model_from_dataclass(
    InclinometerSpec,
    "InclinometerConfig",
    """Inclination sensor noise (SI units); fields of InclinometerSpec.

    Ranges: ``sigma`` at most 1e-3 rad (the default is 1 arc-second) and at most a tenth of
    ``working_range``, else a level instrument would read beyond its range;
    ``working_range`` 1e-4 rad (21 arc-seconds) to 0.1 rad (5.7 deg; the default is 3
    arc-minutes, floor patches tilt by at most 1 deg).
    """,
    {"sigma": Field(ge=0.0, le=1e-3), "working_range": Field(ge=1e-4, le=0.1)},
    __name__,
    base=_InclinometerChecks,
)
OdometryConfig = model_from_dataclass(
    OdometrySpec,
    "OdometryConfig",
    """Wheel odometry drift; fields and defaults of OdometrySpec.

    Ranges: each at most 0.1 (10 % relative errors of the wheel radius and the track; 0.1 m
    and 0.1 rad per square-root metre travelled), twenty to a hundred times the defaults.
    """,
    {
        "wheel_scale_sigma": Field(ge=0.0, le=0.1),
        "track_sigma": Field(ge=0.0, le=0.1),
        "distance_noise": Field(ge=0.0, le=0.1),
        "heading_noise": Field(ge=0.0, le=0.1),
    },
    __name__,
)


class StoppingConfig(Frozen):
    """How far from its goal a robot stops (the geometric fidelity's placement error; the
    render fidelity's robots stop where their controller and odometry leave them).

    Attributes:
        sigma_xy: standard deviation of the stop position on each horizontal axis, m.
        sigma_yaw: standard deviation of the stop heading, rad.
    """

    sigma_xy: Annotated[float, Field(ge=0.0, le=1.0)] = 0.02
    sigma_yaw: Annotated[float, Field(ge=0.0, le=0.5)] = 0.017


class Noise(Frozen):
    """Noise of the instruments, the robots and the LED detection.

    Attributes:
        total_station, inclinometer, odometry: the instruments (paper's Table I defaults).
        stopping: the robots' stopping error (geometric fidelity).
        led_detection_px: standard deviation of each coordinate of a detected LED, px, at
            the geometric fidelity (which projects LEDs instead of rendering them). The
            default is what the render fidelity's detector achieves on the twin's 320 x 240
            images (0.05 px RMS per coordinate, measured over 3-14 m).
        marker_geometry_m: standard deviation of each coordinate of each corner cube and
            LED of a built marker assembly from the geometry the campaign uses (``[marker]``),
            m: how well the assembly was surveyed. Each child's assembly gets its own error,
            drawn once per run. Default 0: the assembly is exactly as specified.
        led_centroid_px: standard deviation of each coordinate of a real camera's LED
            centroid beyond what the twin's images and detector reproduce (interlaced or
            analogue capture, compression, blooming, the LED's shape), px, added to every
            detection at every fidelity. Default 0: the camera is as the twin renders it.
        child_creep_m: standard deviation of each horizontal axis of a standing child's
            shift while the parent drives to its next station, m (its tyres settling, its
            mast leaning: :mod:`twin.sim.rig.creep`). It shows in CPS, which measures the
            child before and after the parent's drive. Default 0: children stand still.
    """

    total_station: TotalStationConfig = TotalStationConfig()  # type: ignore[valid-type]
    inclinometer: InclinometerConfig = InclinometerConfig()  # type: ignore[valid-type]
    odometry: OdometryConfig = OdometryConfig()  # type: ignore[valid-type]
    stopping: StoppingConfig = StoppingConfig()
    led_detection_px: Annotated[float, Field(ge=0.0, le=10.0)] = 0.05
    marker_geometry_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0
    led_centroid_px: Annotated[float, Field(ge=0.0, le=10.0)] = 0.0
    child_creep_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.0
