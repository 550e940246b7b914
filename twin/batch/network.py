"""The global adjustment at the batch fidelity: what each trial measured, kept as the
executor measures it (:class:`NetworkRecorder`), and each trial's network adjusted
(:func:`adjust_trials`) as :mod:`twin.campaign.adjusted_results` adjusts a run's log.

A trial's network is the same as its log's would be: the stations as CPS fixed them, the
children's stands from both stations that measured them, the LED stops of each calibrated
visit (the LEDs the trial found), each camera started from its first calibration. The
adjustment is a sparse least-squares solve per trial (about 75 ms on the paper's hall),
seven times what the batch spends on a trial: it runs only when asked
(``twin montecarlo --adjust``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.metrics import pose_errors
from calib.tsai import tsai_from_vector
from twin.campaign.check.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.campaign.network_log import CampaignNetwork
from twin.localization.adjustment import NothingToAdjustError, adjust_network
from twin.localization.network import NetworkBuilder


class Event(Protocol):
    """A measurement of T trials, as (T, ...) arrays."""

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        """Give trial ``k``'s measurement to its network."""


@dataclass(frozen=True)
class Station:
    """A CPS fix: yaw (T,) rad, centre (T, 3) m."""

    yaw: NDArray[np.float64]
    centre: NDArray[np.float64]

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        net.builder.station(float(self.yaw[k]), self.centre[k])


@dataclass(frozen=True)
class Stand:
    """A child placed: level (T, 3) m, covariance (T, 3, 3) m^2, world (T, 3) m."""

    child: str
    level: NDArray[np.float64]
    covariance: NDArray[np.float64]
    world: NDArray[np.float64]

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        net.builder.stand(self.child, self.level[k], self.covariance[k], self.world[k])


@dataclass(frozen=True)
class Sight:
    """A standing child measured at a fix: level (T, 3) m, covariance (T, 3, 3) m^2."""

    child: str
    level: NDArray[np.float64]
    covariance: NDArray[np.float64]

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        net.builder.sight_child(self.child, self.level[k], self.covariance[k])


@dataclass(frozen=True)
class Stop:
    """An LED stop of a visit: leds_world (T, N, 3) m (NaN for the LEDs a trial gave up),
    covariance (T, 3N, 3N) m^2, pixels (T, N, 2), the child and its survey loading
    (T, 3N, M) or None (:attr:`twin.campaign.records.DataPoint.survey_loading`)."""

    camera: str
    visit: int
    leds_world: NDArray[np.float64]
    covariance: NDArray[np.float64]
    pixels: NDArray[np.float64]
    child: str
    survey: NDArray[np.float64] | None

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        survey = None if self.survey is None else self.survey[k]
        net.stop(
            self.camera,
            self.visit,
            self.leds_world[k],
            self.covariance[k],
            self.pixels[k],
            self.child,
            survey,
        )


@dataclass(frozen=True)
class Calibrated:
    """A visit calibrated from its first ``points`` LED points: the T cameras and (T,)
    which trials it calibrated."""

    camera: str
    visit: int
    cameras: TsaiCameras
    calibrated: NDArray[np.bool_]
    points: int

    def feed(self, net: CampaignNetwork, k: int, pixel_noise_px: Mapping[str, float]) -> None:
        if self.calibrated[k]:
            sigma = max(float(pixel_noise_px[self.camera]), 1e-3)  # noise-free pixels too
            net.calibrated(self.camera, self.visit, self.cameras.camera(k), self.points, sigma)


@dataclass
class NetworkRecorder:
    """The measurements of T trials in the order they were made (arrays over the trials):
    each trial's network is its log's (:class:`twin.campaign.network_log.CampaignNetwork`),
    one camera per camera started from its first successful calibration."""

    events: list[Event] = field(default_factory=list)

    def station(self, yaw: NDArray, centre: NDArray) -> None:
        self.events.append(Station(np.array(yaw), np.array(centre)))

    def stand(self, child: str, level: NDArray, cov: NDArray, world: NDArray) -> None:
        self.events.append(Stand(child, np.array(level), np.array(cov), np.array(world)))

    def sight(self, child: str, level: NDArray, cov: NDArray) -> None:
        self.events.append(Sight(child, np.array(level), np.array(cov)))

    def stop(
        self,
        camera: str,
        visit: int,
        leds_world: NDArray,
        cov_world: NDArray,
        pixels: NDArray,
        child: str = "",
        survey: NDArray | None = None,
    ) -> None:
        self.events.append(
            Stop(
                camera,
                visit,
                np.array(leds_world),
                np.array(cov_world),
                np.array(pixels),
                child,
                None if survey is None else np.array(survey),
            )
        )

    def calibrated(
        self, camera: str, visit: int, cameras: TsaiCameras, calibrated: NDArray, points: int
    ) -> None:
        self.events.append(Calibrated(camera, visit, cameras, np.array(calibrated), points))

    def network(
        self,
        k: int,
        pixel_noise_px: Mapping[str, float],
        child_creep_m: float = 0.0,
    ) -> tuple[NetworkBuilder, dict[tuple[str, int], tuple[int, ...]]]:
        """Trial ``k``'s network and the LED stops of each calibrated visit."""
        net = CampaignNetwork(child_creep_m)
        for event in self.events:
            event.feed(net, k, pixel_noise_px)
        return net.builder, dict(zip(net.calibrations, net.calibration_stops, strict=True))


@dataclass(frozen=True)
class AdjustedVisits:
    """Each visit's camera in the adjustment of every trial (NaN where a trial has none).

    Attributes:
        position_error: (T,) m. rotation_error: (T,) rad. position_offset: (T, 3)
            adjusted minus true centre, m. predicted: (T,) RMS of the adjusted centre's
            predicted error, m.
    """

    position_error: NDArray[np.float64]
    rotation_error: NDArray[np.float64]
    position_offset: NDArray[np.float64]
    predicted: NDArray[np.float64]


def adjust_trials(
    recorder: NetworkRecorder,
    trials: int,
    truths: Mapping[str, TsaiCamera],
    pixel_noise_px: Mapping[str, float],
    child_creep_m: float = 0.0,
    visits: Sequence[tuple[str, int]] = (),
) -> dict[tuple[str, int], AdjustedVisits]:
    """Adjust each trial's network; per visit, its adjusted camera against the truth.

    A trial with nothing measured twice (a camera calibrated once only), or whose network
    the solver cannot solve, has NaN."""
    out = {
        v: AdjustedVisits(
            np.full(trials, np.nan),
            np.full(trials, np.nan),
            np.full((trials, 3), np.nan),
            np.full(trials, np.nan),
        )
        for v in visits
    }
    for k in range(trials):
        builder, groups = recorder.network(k, pixel_noise_px, child_creep_m)
        try:
            adjusted = adjust_network(builder.build())
        except (NothingToAdjustError, ValueError, RuntimeError, np.linalg.LinAlgError):
            continue  # nothing measured twice, or a network the solver cannot solve: NaN
        # A network that fails the global test scales its covariances (as a run's does).
        scale = 1.0 if adjusted.passes(DEFAULT_FALSE_ALARM_RATE) else adjusted.variance_factor
        for (camera, visit), _ in groups.items():
            if (camera, visit) not in out:
                continue
            c = builder.camera_labels.index(camera)
            cam = tsai_from_vector(adjusted.cameras[c], builder.sizes[c])
            truth = truths[camera]
            v = out[(camera, visit)]
            errors = pose_errors(TsaiCameras.from_cameras([cam]), truth)
            v.position_offset[k] = cam.position - truth.position
            v.position_error[k] = errors.position_m[0]
            v.rotation_error[k] = errors.rotation_rad[0]
            v.predicted[k] = np.sqrt(scale * np.trace(adjusted.camera_covariances[c][8:, 8:]))
    return out
