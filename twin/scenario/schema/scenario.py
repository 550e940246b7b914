"""The whole scenario: its sections, ``[sim]`` and ``[site]``."""

from __future__ import annotations

import dataclasses
import math
from typing import Annotated

from pydantic import Field

from twin.instruments.total_station import TotalStationSpec
from twin.scenario.limits import MAX_CAMERAS, MAX_PEOPLE, AngleDeg, Coordinate, Seed
from twin.scenario.schema.cameras import CameraConfig
from twin.scenario.schema.campaign_settings import CampaignSettings, ControlPoint
from twin.scenario.schema.faults import Faults
from twin.scenario.schema.fleet import MarkerConfig, RobotConfig, Robots
from twin.scenario.schema.frozen import Frozen, Name
from twin.scenario.schema.instrument_noise import (
    InclinometerConfig,
    Noise,
    OdometryConfig,
    StoppingConfig,
    TotalStationConfig,
)
from twin.scenario.schema.paths import Person, Route
from twin.scenario.schema.space import Space
from twin.scenario.schema.visits import Calibration


class SimConfig(Frozen):
    """Simulation settings.

    Attributes:
        timestep: physics time step, s.
    """

    timestep: Annotated[float, Field(ge=2e-4, le=0.01)] = 0.002


class SiteInfo(Frozen):
    """Where a scenario planned from a map (``twin site``) came from.

    Attributes:
        map: the map file it was planned from (relative to the scenario's folder, or
            absolute).
        map_pose: W in the map's frame: the parent's first station (x, y) m and W's x-axis
            from the map's x-axis, degrees counter-clockwise. A point (x, y) of W is
            ``(X + x cos a - y sin a, Y + x sin a + y cos a)`` in the map.
        resolution: the grid the map's blocked floor was laid on as boxes, m.
    """

    map: Annotated[str, Field(min_length=1, max_length=400)]
    map_pose: tuple[Coordinate, Coordinate, AngleDeg] = (0.0, 0.0, 0.0)
    resolution: Annotated[float, Field(gt=0.0, le=10.0)] = 0.1


class Scenario(Frozen):
    """A complete scenario. See ``scenarios/paper_hall.toml`` for a documented example.

    Attributes:
        name: identifier.
        description: free text.
        seed: root seed of every random generator of a run, 0 to 2**63 - 1 (see
            ``twin.scenario.limits.MAX_SEED``).
        space, cameras, robots, marker, noise, route, calibration, sim: the sections; at
            most ``MAX_CAMERAS`` cameras.
        people: people walking through the space (distractors), none by default, at most
            ``MAX_PEOPLE``.
        campaign: how the calibration campaign runs.
        control_points: points the parent measures when it passes (none by default; at
            most ``MAX_CAMERAS``): see :class:`ControlPoint`.
        faults: faults injected into the simulated devices (none by default).
        site: where a scenario planned from a map came from, and the map-to-W transform
            (None for a scenario written by hand).
        source: the file it was loaded from (set by the loader).
    """

    name: Name
    description: str = ""
    seed: Seed
    space: Space
    cameras: tuple[CameraConfig, ...] = Field(min_length=1, max_length=MAX_CAMERAS)
    robots: Robots
    marker: MarkerConfig = MarkerConfig()
    noise: Noise = Noise()
    route: Route
    calibration: Calibration
    sim: SimConfig = SimConfig()
    people: tuple[Person, ...] = Field(default=(), max_length=MAX_PEOPLE)
    campaign: CampaignSettings = CampaignSettings()
    control_points: tuple[ControlPoint, ...] = Field(default=(), max_length=MAX_CAMERAS)
    faults: Faults = Faults()
    site: SiteInfo | None = None
    source: str = ""

    def without_noise(self) -> Scenario:
        """The same scenario with every noise source off: a perfect total station (no noise,
        no output rounding) and inclinometer, exact odometry, exact stops, exact LED
        detection at the geometric fidelity, and cameras without sensor noise."""
        ts = dataclasses.replace(
            TotalStationSpec.noiseless(),
            range_min=self.noise.total_station.range_min,
            range_max=self.noise.total_station.range_max,
            aim_cone=self.noise.total_station.aim_cone,
        )
        noise = Noise(
            total_station=TotalStationConfig(**dataclasses.asdict(ts)),
            inclinometer=InclinometerConfig(
                sigma=0.0, working_range=self.noise.inclinometer.working_range
            ),
            odometry=OdometryConfig(
                wheel_scale_sigma=0.0, track_sigma=0.0, distance_noise=0.0, heading_noise=0.0
            ),
            stopping=StoppingConfig(sigma_xy=0.0, sigma_yaw=0.0),
            led_detection_px=0.0,
            marker_geometry_m=0.0,
            led_centroid_px=0.0,
            child_creep_m=0.0,
        )
        cameras = tuple(
            c.model_copy(
                update={
                    "sensor": c.sensor.model_copy(update={"noise": False}),
                    "led_centroid_px": None if c.led_centroid_px is None else 0.0,
                }
            )
            for c in self.cameras
        )
        return self.model_copy(update={"noise": noise, "cameras": cameras})

    def led_centroid_px(self, camera: str) -> float:
        """The LED centroid error of camera ``camera``, px: its own, else the noise
        section's."""
        own = self.camera(camera).led_centroid_px
        return self.noise.led_centroid_px if own is None else own

    def projected_led_px(self, camera: str) -> float:
        """Standard deviation of each coordinate of an LED that camera ``camera`` sees,
        projected instead of rendered (geometric and batch fidelities), px: the detector's
        and the camera's centroid error in quadrature."""
        centroid = self.led_centroid_px(camera)
        if centroid == 0.0:
            return self.noise.led_detection_px
        return math.hypot(self.noise.led_detection_px, centroid)

    def camera(self, name: str) -> CameraConfig:
        """The camera called ``name``; KeyError naming the known cameras otherwise."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        known = ", ".join(c.name for c in self.cameras)
        raise KeyError(f"no camera {name!r} in scenario {self.name!r}; cameras: {known}")

    def robot(self, name: str) -> RobotConfig:
        """The robot called ``name``; KeyError naming the known robots otherwise."""
        for robot in self.robots.all:
            if robot.name == name:
                return robot
        known = ", ".join(r.name for r in self.robots.all)
        raise KeyError(f"no robot {name!r} in scenario {self.name!r}; robots: {known}")
