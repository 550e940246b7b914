"""A whole campaign's measurements as one network, for the global adjustment.

CPS chains each station on the last (:mod:`.sequence`) and never looks back; the network
keeps every measurement so that :mod:`.adjustment` can solve them all at once:

- **stations**: the parent's levelled instrument frames, ``(yaw, x, y, z)`` in W; station 0
  is the first, which defines W, and stays fixed.
- **targets**: points the parent measured from more than one station: a child's stand (its
  reference point while it stood still) or a control point (a prism left in place, or a
  surveyed mark whose world coordinates are known).
- **point sightings**: a target measured from a station, as a point of the levelled frame
  with its covariance (the total station's and the inclinometer's noise).
- **LED sightings**: one stop of a child in a camera's view: its LEDs in the levelled frame
  of the station that measured them (with their joint covariance, from the marker pose)
  and where the camera found them; with their loading on the child's marker survey error
  where the assembly is not known exactly (the same error at every stop of the child:
  :func:`twin.instruments.marker_pose.survey_loading`).
- **cameras**: Tsai's eleven parameters (:func:`calib.tsai.tsai_vector`) of each camera, or
  of each calibration when the visits of one camera are not to be tied together.

Every array is in SI units (m, rad) and W unless its name says otherwise; pixels in px.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from calib.rotation import rot_z
from calib.tsai import N_TSAI

STATION_DOF = 4
"""Unknowns of a station: yaw about the vertical (rad) and the instrument centre (m)."""


@dataclass(frozen=True, eq=False)
class PointSighting:
    """A target measured from a station.

    Attributes:
        station: the station's index. target: the target's index.
        point_level: (3,) the target in the station's levelled frame, m.
        covariance: (3, 3) of ``point_level``, m^2.
    """

    station: int
    target: int
    point_level: NDArray[np.float64]
    covariance: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class LedSighting:
    """One stop of a child in a camera's view.

    Attributes:
        station: the index of the station that measured the child.
        camera: the index of the camera (or calibration) that saw the LEDs.
        leds_level: (N, 3) LED positions in the station's levelled frame, m.
        covariance_level: (3N, 3N) their joint covariance (the marker pose's), m^2.
        pixels: (N, 2) where the camera found them, px.
        child: the child whose LEDs they are.
        survey_level: (3N, M) the LEDs' error in the levelled frame per unit of the (M,)
            standard normal survey error of ``child``'s assembly, m; empty where it is
            known exactly.
    """

    station: int
    camera: int
    leds_level: NDArray[np.float64]
    covariance_level: NDArray[np.float64]
    pixels: NDArray[np.float64]
    child: str = ""
    survey_level: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)))


@dataclass(frozen=True, eq=False)
class Network:
    """Everything one adjustment solves, with the sequential estimates as its start.

    Attributes:
        stations: (K, 4) (yaw rad, x, y, z m) of each station as CPS estimated it; row 0
            defines W.
        targets: (M, 3) each target's world position as first estimated, m.
        known_targets: (M,) True for a control point whose world coordinates are known
            (surveyed): it is not adjusted.
        control_targets: (M,) True for a control point, False for a child's stand.
        cameras: (C, 11) each camera's parameters as first calibrated.
        image_sizes: (C, 2) their image sizes, px.
        pixel_noise_px: (C,) standard deviation of the LED detector's pixels on each axis,
            px.
        point_sightings, led_sightings: the measurements.
        camera_labels, target_labels: names for messages and results.
    """

    stations: NDArray[np.float64]
    targets: NDArray[np.float64]
    known_targets: NDArray[np.bool_]
    control_targets: NDArray[np.bool_]
    cameras: NDArray[np.float64]
    image_sizes: NDArray[np.int64]
    pixel_noise_px: NDArray[np.float64]
    point_sightings: tuple[PointSighting, ...]
    led_sightings: tuple[LedSighting, ...]
    camera_labels: tuple[str, ...] = ()
    target_labels: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        k, m, c = len(self.stations), len(self.targets), len(self.cameras)
        if self.stations.shape != (k, STATION_DOF) or k < 1:
            raise ValueError(f"stations must be (K >= 1, 4), got {self.stations.shape}")
        if (
            self.targets.shape != (m, 3)
            or self.known_targets.shape != (m,)
            or self.control_targets.shape != (m,)
        ):
            raise ValueError(
                f"targets must be (M, 3) with (M,) known and control flags, got "
                f"{self.targets.shape}, {self.known_targets.shape}, {self.control_targets.shape}"
            )
        if self.cameras.shape != (c, N_TSAI) or self.image_sizes.shape != (c, 2):
            raise ValueError(
                f"cameras must be (C, {N_TSAI}) with (C, 2) image sizes, got "
                f"{self.cameras.shape} and {self.image_sizes.shape}"
            )
        if self.pixel_noise_px.shape != (c,) or not np.all(self.pixel_noise_px > 0):
            raise ValueError(f"pixel noise must be (C,) and positive, got {self.pixel_noise_px}")
        for s in self.point_sightings:
            if not (0 <= s.station < k and 0 <= s.target < m):
                raise ValueError(f"a point sighting names station {s.station}, target {s.target}")
        for s in self.led_sightings:
            if not (0 <= s.station < k and 0 <= s.camera < c):
                raise ValueError(f"an LED sighting names station {s.station}, camera {s.camera}")

    def sightings_of_targets(self) -> NDArray[np.int64]:
        """(M,) how many times each target was measured."""
        return np.bincount(
            [s.target for s in self.point_sightings], minlength=len(self.targets)
        ).astype(np.int64)

    def stations_of_cameras(self) -> list[set[int]]:
        """The stations from which each camera's data were measured."""
        out: list[set[int]] = [set() for _ in range(len(self.cameras))]
        for s in self.led_sightings:
            out[s.camera].add(s.station)
        return out

    def redundancy(self) -> list[str]:
        """What the network measured twice beyond a chain of CPS steps, in words: a camera
        whose data came from more than one station, a control point measured from more than
        one station or a surveyed one. Empty: the adjustment has nothing to add to CPS."""
        found = []
        for label, stations in zip(self._camera_names(), self.stations_of_cameras(), strict=True):
            if len(stations) > 1:
                found.append(f"camera {label} from stations {sorted(stations)}")
        counts = self.sightings_of_targets()
        names = self.target_labels or tuple(f"target {i}" for i in range(len(self.targets)))
        for i in np.flatnonzero(self.control_targets):
            name = names[i]
            if self.known_targets[i] and counts[i] >= 1:
                found.append(f"{name} (surveyed)")
            elif counts[i] > 1:
                seen = sorted({s.station for s in self.point_sightings if s.target == i})
                if len(seen) > 1:
                    found.append(f"{name} from stations {seen}")
        return found

    def _camera_names(self) -> tuple[str, ...]:
        return self.camera_labels or tuple(f"camera {i}" for i in range(len(self.cameras)))


class NetworkBuilder:
    """A network assembled measurement by measurement, in the order a campaign makes them.

    Stations are added as the parent fixes them (:meth:`station`); a child placed from the
    current station starts a new stand (:meth:`stand`), and the later sightings of that
    child (:meth:`sight_child`) are of that stand, with the child's creep added once per
    parent fix since it was placed; control points are sighted by name
    (:meth:`sight_control`); LED stops are seen from the current station (:meth:`stop`).

    Args:
        child_creep_m: how far a standing child may creep on each horizontal axis while
            the parent drives, m.
        surveyed: the surveyed world coordinates (3,) of control points by name, m.
    """

    def __init__(
        self, child_creep_m: float = 0.0, surveyed: Mapping[str, NDArray[np.float64]] | None = None
    ) -> None:
        self.creep = float(child_creep_m)
        self.surveyed = dict(surveyed or {})
        self.stations: list[NDArray[np.float64]] = []
        self.targets: list[NDArray[np.float64]] = []
        self.known: list[bool] = []
        self.control: list[bool] = []
        self.labels: list[str] = []
        self.sightings: list[PointSighting] = []
        self.leds: list[LedSighting] = []
        self.cameras: list[NDArray[np.float64]] = []
        self.sizes: list[tuple[int, int]] = []
        self.sigmas: list[float] = []
        self.camera_labels: list[str] = []
        self._stand: dict[str, tuple[int, int]] = {}
        self._controls: dict[str, int] = {}

    @property
    def current(self) -> int:
        """The index of the current station."""
        return len(self.stations) - 1

    def station(self, yaw: float, translation: NDArray[np.float64]) -> None:
        """The parent fixed a new station: its estimate (yaw rad, (3,) centre m)."""
        self.stations.append(np.concatenate([[float(yaw)], np.asarray(translation, float)]))

    def _target(self, world: NDArray, label: str, known: bool, control: bool) -> int:
        self.targets.append(np.asarray(world, dtype=float).reshape(3))
        self.known.append(known)
        self.control.append(control)
        self.labels.append(label)
        return len(self.targets) - 1

    def _sight(self, target: int, level: NDArray, cov: NDArray, creep: float = 0.0) -> None:
        c = np.asarray(cov, dtype=float).reshape(3, 3).copy()
        c[0, 0] += creep
        c[1, 1] += creep
        point = np.asarray(level, dtype=float).reshape(3)
        self.sightings.append(PointSighting(self.current, target, point, c))

    def stand(self, child: str, level: NDArray, cov: NDArray, world: NDArray) -> None:
        """A child placed from the current station: a new stand, first seen here."""
        target = self._target(world, f"stand of {child}", False, False)
        self._stand[child] = (target, self.current)
        self._sight(target, level, cov)

    def sight_child(self, child: str, level: NDArray, cov: NDArray) -> None:
        """A standing child measured again from the current station (a CPS fix)."""
        target, placed = self._stand[child]
        self._sight(target, level, cov, self.creep**2 * (self.current - placed))

    def sight_control(self, name: str, level: NDArray, cov: NDArray) -> None:
        """A control point measured from the current station."""
        if name not in self._controls:
            pose = self.stations[-1]
            given = self.surveyed.get(name)
            world = rot_z(pose[0]) @ np.asarray(level, float) + pose[1:] if given is None else given
            self._controls[name] = self._target(
                world, f"control point {name}", given is not None, True
            )
        self._sight(self._controls[name], level, cov)

    def camera(self, q: NDArray, image_size: tuple[int, int], sigma_px: float, label: str) -> int:
        """A camera's (11,) start parameters; its index."""
        self.cameras.append(np.asarray(q, dtype=float))
        self.sizes.append((int(image_size[0]), int(image_size[1])))
        self.sigmas.append(float(sigma_px))
        self.camera_labels.append(label)
        return len(self.cameras) - 1

    def stop(
        self,
        station: int,
        camera: int,
        leds_world: NDArray,
        covariance_world: NDArray,
        pixels: NDArray,
        child: str = "",
        survey_world: NDArray | None = None,
    ) -> None:
        """An LED stop measured from ``station`` and mapped to W with its estimate then:
        (N, 3) LEDs in W, m, their (3N, 3N) covariance in W, (N, 2) pixels; the child and
        the LEDs' (3N, M) loading in W on its marker survey error (None or empty: known
        exactly)."""
        pose = self.stations[station]
        world = np.asarray(leds_world, dtype=float).reshape(-1, 3)
        turn = np.kron(np.eye(len(world)), rot_z(pose[0]))
        level = (world - pose[1:]) @ rot_z(pose[0])
        cov = turn.T @ np.asarray(covariance_world, dtype=float) @ turn
        survey = np.zeros((0, 0)) if survey_world is None else np.asarray(survey_world, float)
        if survey.size:
            survey = turn.T @ survey.reshape(3 * len(world), -1)
        self.leds.append(
            LedSighting(station, camera, level, cov, np.asarray(pixels, float), child, survey)
        )

    def build(self) -> Network:
        """The network of everything added."""
        return Network(
            stations=np.array(self.stations).reshape(-1, STATION_DOF),
            targets=np.array(self.targets).reshape(-1, 3),
            known_targets=np.array(self.known, dtype=bool),
            control_targets=np.array(self.control, dtype=bool),
            cameras=np.array(self.cameras).reshape(-1, N_TSAI),
            image_sizes=np.array(self.sizes, dtype=np.int64).reshape(-1, 2),
            pixel_noise_px=np.array(self.sigmas),
            point_sightings=tuple(self.sightings),
            led_sightings=tuple(self.leds),
            camera_labels=tuple(self.camera_labels),
            target_labels=tuple(self.labels),
        )
