"""The robots as scenarios see them: Pioneer dimensions, motion limits, odometry errors.

These numbers describe the MJCF models in ``models/pioneer3at`` and ``models/pioneer3dx``
(a test checks that they agree). They are kept free of MuJoCo (and of :mod:`twin.sim`) so
that scenario validation, the geometric fidelity and the campaign code can use them.

Motion limits: the P3-AT's rated top speed is 0.7 m/s and the P3-DX's 1.2 m/s (MobileRobots
data sheets). The accelerations and turn rates are deliberately conservative (a total
station and a 1.4 m mast ride on these robots): 0.3 m/s^2 for the P3-AT, 0.5 m/s^2 for
the P3-DX, and turn rates well below the rated 140 and 300 deg/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"


@dataclass(frozen=True)
class Platform:
    """A wheeled robot's geometry and limits.

    Attributes:
        model: folder name under ``models/`` (also the MJCF file's stem).
        length, width, height: overall size of the body (wheels included), m.
        wheel_radius: m.
        track: distance between the left and right wheel centres, m.
        max_speed: forward speed limit, m/s.
        max_accel: forward acceleration limit, m/s^2.
        max_yaw_rate: turn rate limit, rad/s.
        max_yaw_accel: turn acceleration limit, rad/s^2.
        ground_clearance: height of the chassis' underside above the floor, m. Only the
            chassis collides with obstacles (the wheels touch the floor only), so anything
            lower than this passes under the robot.
        wheels_left, wheels_right: names of the driven wheel joints (= actuators).
        effective_track: kinematic track width, m: the measured wheel rotation of each
            side (as distance rolled, ``r dphi``) and the yaw actually turned satisfy
            ``dyaw = (d_right - d_left) / effective_track``. Odometry uses it. Larger than
            ``track`` for a skid-steered robot, whose wheels slip sideways when it turns;
            measured on the model from wheel angles and yaw (see the model's README).
        command_track: track width used to turn (v, w) commands into wheel-speed commands,
            m. It also absorbs the wheel servos' speed-tracking error, so that a commanded
            yaw rate is about the one obtained; it is *not* the odometry's track.
    """

    model: str
    length: float
    width: float
    height: float
    wheel_radius: float
    track: float
    max_speed: float
    max_accel: float
    max_yaw_rate: float
    max_yaw_accel: float
    ground_clearance: float
    wheels_left: tuple[str, ...]
    wheels_right: tuple[str, ...]
    effective_track: float
    command_track: float

    @property
    def radius(self) -> float:
        """Radius of the circle that encloses the body's footprint, m."""
        return 0.5 * (self.length**2 + self.width**2) ** 0.5

    @property
    def xml_path(self) -> Path:
        """Path of the device's MJCF file."""
        return MODELS_DIR / self.model / f"{self.model}.xml"


PIONEER3AT = Platform(
    model="pioneer3at",
    length=0.50,
    width=0.49,
    height=0.26,
    wheel_radius=0.11,
    track=0.40,
    max_speed=0.7,
    max_accel=0.3,
    max_yaw_rate=0.8,
    max_yaw_accel=1.0,
    ground_clearance=0.08,
    wheels_left=("front_left_wheel", "rear_left_wheel"),
    wheels_right=("front_right_wheel", "rear_right_wheel"),
    effective_track=0.85,
    command_track=1.0,
)

PIONEER3DX = Platform(
    model="pioneer3dx",
    length=0.44,
    width=0.38,
    height=0.22,
    wheel_radius=0.0975,
    track=0.33,
    max_speed=1.2,
    max_accel=0.5,
    max_yaw_rate=1.2,
    max_yaw_accel=2.0,
    ground_clearance=0.05,
    wheels_left=("left_wheel",),
    wheels_right=("right_wheel",),
    effective_track=0.33,
    command_track=0.33,
)

PLATFORMS: dict[str, Platform] = {p.model: p for p in (PIONEER3AT, PIONEER3DX)}

# Height of the total station's origin (vertical axis meets trunnion axis) above the floor
# under the parent robot, m: the ``instrument`` site of models/pioneer3at.
INSTRUMENT_HEIGHT = 0.40


@dataclass(frozen=True)
class OdometrySpec:
    """Error model of wheel odometry.

    Attributes:
        wheel_scale_sigma: standard deviation of the relative error of each side's
            believed wheel radius, drawn once per robot (dimensionless). Default 0.1 %.
        track_sigma: standard deviation of the relative error of the believed effective
            track width, drawn once per robot (dimensionless). Default 0.5 %.
        distance_noise: random error of the travelled distance, m per sqrt(m) travelled.
        heading_noise: random error of the heading, rad per sqrt(m) travelled.
    """

    wheel_scale_sigma: float = 0.001
    track_sigma: float = 0.005
    distance_noise: float = 0.005
    heading_noise: float = 0.003
