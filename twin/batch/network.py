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
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera, TsaiCameras
from calib.metrics import pose_errors
from calib.tsai import tsai_from_vector, tsai_vector
from twin.campaign.check.consistency import DEFAULT_FALSE_ALARM_RATE
from twin.localization.adjustment import NothingToAdjustError, adjust_network
from twin.localization.network import NetworkBuilder


@dataclass
class NetworkRecorder:
    """The measurements of T trials in the order they were made (arrays over the trials).

    Each event is a tuple: ``("station", yaw (T,), centre (T, 3))``; ``("stand", child,
    level (T, 3), covariance (T, 3, 3), world (T, 3))``; ``("sight", child, level,
    covariance)``; ``("stop", camera, visit, leds_world (T, N, 3), covariance_world
    (T, 3N, 3N), pixels (T, N, 2), child, survey (T, 3N, M) or None)`` (NaN for the LEDs a
    trial gave up; the survey loading: :attr:`twin.campaign.records.DataPoint.
    survey_loading`);
    ``("calibrated", camera, visit, cameras, calibrated (T,), points)``.
    """

    events: list[tuple] = field(default_factory=list)

    def station(self, yaw: NDArray, centre: NDArray) -> None:
        self.events.append(("station", np.array(yaw), np.array(centre)))

    def stand(self, child: str, level: NDArray, cov: NDArray, world: NDArray) -> None:
        self.events.append(("stand", child, np.array(level), np.array(cov), np.array(world)))

    def sight(self, child: str, level: NDArray, cov: NDArray) -> None:
        self.events.append(("sight", child, np.array(level), np.array(cov)))

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
            (
                "stop",
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
        self.events.append(("calibrated", camera, visit, cameras, np.array(calibrated), points))

    def network(
        self,
        k: int,
        pixel_noise_px: Mapping[str, float],
        child_creep_m: float = 0.0,
    ) -> tuple[NetworkBuilder, dict[tuple[str, int], tuple[int, ...]]]:
        """Trial ``k``'s network (one camera per camera, started from its first successful
        calibration) and the LED stops of each calibrated visit."""
        net = NetworkBuilder(child_creep_m)
        stops: dict[tuple[str, int], list[tuple[Any, ...]]] = {}
        cameras: dict[str, int] = {}
        groups: dict[tuple[str, int], tuple[int, ...]] = {}
        for event in self.events:
            kind = event[0]
            if kind == "station":
                net.station(float(event[1][k]), event[2][k])
            elif kind == "stand":
                net.stand(event[1], event[2][k], event[3][k], event[4][k])
            elif kind == "sight":
                net.sight_child(event[1], event[2][k], event[3][k])
            elif kind == "stop":
                _, camera, visit, world, cov, pixels, child, survey = event
                stops.setdefault((camera, visit), []).append(
                    (
                        net.current,
                        world[k],
                        cov[k],
                        pixels[k],
                        child,
                        None if survey is None else survey[k],
                    )
                )
            elif kind == "calibrated":
                _, camera, visit, cams, ok, points = event
                if not ok[k]:
                    continue
                model = cams.camera(k)
                if camera not in cameras:
                    sigma = max(float(pixel_noise_px[camera]), 1e-3)
                    cameras[camera] = net.camera(
                        tsai_vector(model), model.image_size, sigma, camera
                    )
                first, left = len(net.leds), int(points)
                for station, world, cov, pixels, child, survey in stops.get((camera, visit), []):
                    if left <= 0:
                        break
                    n = min(left, len(world))
                    left -= n
                    seen = np.isfinite(world[:n]).all(axis=1) & np.isfinite(pixels[:n]).all(axis=1)
                    if not seen.any():
                        continue
                    rows = np.repeat(seen, 3)
                    block = cov[: 3 * n, : 3 * n][np.ix_(rows, rows)]
                    net.stop(
                        station,
                        cameras[camera],
                        world[:n][seen],
                        block,
                        pixels[:n][seen],
                        child,
                        None if survey is None else survey[: 3 * n][rows],
                    )
                groups[(camera, visit)] = tuple(range(first, len(net.leds)))
        return net, groups


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
