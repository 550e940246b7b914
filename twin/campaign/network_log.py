"""A campaign's measurements as a network for the global adjustment
(:mod:`twin.localization.network`): :class:`CampaignNetwork` takes them in the order they
were made, from a run's log (:func:`network_from_log`) or from one trial of the batch
fidelity (:class:`twin.batch.network.NetworkRecorder`).

The campaign records what the adjustment needs as it goes (:mod:`twin.campaign.records`):

- each CPS fix (``ParentFix``): the station's sequential pose and the children measured
  from it (``children_level``, ``children_covariance``): sightings of their current stands;
- each child placed (``ChildPlaced``): a new stand of that child, seen from the current
  station;
- each data point of a visit (``DataPoint``): an LED stop seen from the current station
  (turned back into its levelled frame with the pose it was mapped with);
- each calibration (``CalibrationRecord``): the camera's first estimate, and how many of
  the visit's LED points its data set holds;
- each control point measured (``ControlSighting``): a sighting of the control point.

The reference data sets (taken at the first station to check the calibrations, Table III's
world errors) are left out: they judge the result, and would calibrate the cameras from
the first station if they were used.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from calib.camera import TsaiCamera
from calib.io.camera_files import camera_from_dict
from calib.tsai import tsai_vector
from twin.campaign.records import CALIBRATION, CHILD_PLACED, CONTROL_SIGHTING, PARENT_FIX, POINT
from twin.localization.network import Network, NetworkBuilder

CAMERA_MODES = ("shared", "per_visit")
"""How the adjustment treats a camera calibrated at more than one visit: one camera (it did
not move: the paper's own information) or one camera per calibration (tied only through
the stations: control points)."""


@dataclass(frozen=True)
class NetworkIndex:
    """What the network's indices stand for.

    Attributes:
        camera_keys: (camera, visit) of each network camera (visit 0 in ``shared`` mode).
        calibrations: (camera, visit) of each calibration, in the log's order.
        calibration_stops: for each calibration, the indices of its LED sightings.
        stations_time: (K,) when each station was fixed, s.
    """

    camera_keys: tuple[tuple[str, int], ...]
    calibrations: tuple[tuple[str, int], ...]
    calibration_stops: tuple[tuple[int, ...], ...]
    stations_time: tuple[float, ...]

    def camera_of(self, camera: str, visit: int, mode: str) -> int:
        """The network camera of a calibration."""
        return self.camera_keys.index((camera, 0 if mode == "shared" else visit))


class LogNetworkError(ValueError):
    """The log lacks what the adjustment needs."""


def _a(values: Any) -> NDArray[np.float64]:
    return np.asarray([np.nan if v is None else v for v in np.ravel(values)], dtype=float).reshape(
        np.shape(values)
    )


class CampaignNetwork:
    """A network assembled from a campaign's measurements in the order it made them.

    The stations, stands and sightings go straight to the network
    (:class:`twin.localization.network.NetworkBuilder`: :attr:`builder`); an LED stop is
    kept with its station until a calibration of its visit says how many of the visit's
    LED points its data set holds (:meth:`calibrated`).

    Args:
        child_creep_m: how far a standing child may creep on each horizontal axis while the
            parent drives, m.
        control_points: surveyed world coordinates (3,) of control points by name, m.
    """

    def __init__(
        self,
        child_creep_m: float = 0.0,
        control_points: Mapping[str, NDArray[np.float64]] | None = None,
    ) -> None:
        self.builder = NetworkBuilder(child_creep_m, control_points)
        self.camera_keys: list[tuple[str, int]] = []
        self.calibrations: list[tuple[str, int]] = []
        self.calibration_stops: list[tuple[int, ...]] = []
        self._stops: dict[tuple[str, int], list[tuple[int, tuple[Any, ...]]]] = {}

    def stop(
        self,
        camera: str,
        visit: int,
        leds_world: NDArray[np.float64],
        covariance_world: NDArray[np.float64],
        pixels: NDArray[np.float64],
        child: str = "",
        survey_world: NDArray[np.float64] | None = None,
    ) -> None:
        """An LED stop of a visit from the current station: (N, 3) LEDs in W, m (NaN where
        not found), their (3N, 3N) covariance in W, (N, 2) pixels, the child and the LEDs'
        (3N, M) loading on its marker survey error (None: known exactly)."""
        stop = (leds_world, covariance_world, pixels, child, survey_world)
        self._stops.setdefault((camera, visit), []).append((self.builder.current, stop))

    def calibrated(
        self,
        camera: str,
        visit: int,
        model: TsaiCamera,
        points: int,
        sigma_px: float,
        per_visit: bool = False,
    ) -> tuple[int, ...]:
        """A calibration of a visit from the first ``points`` LED points of its stops (the
        LEDs found): those LED sightings of the camera, started from ``model`` where it is
        new (one camera per camera, or per visit with ``per_visit``) with ``sigma_px``
        pixel noise, px. Returns the indices of the LED sightings."""
        key = (camera, visit if per_visit else 0)
        if key not in self.camera_keys:
            label = f"{camera} visit {visit}" if per_visit else camera
            self.builder.camera(tsai_vector(model), model.image_size, sigma_px, label)
            self.camera_keys.append(key)
        net = self.builder
        first, left = len(net.leds), int(points)
        for station, (world, cov, pixels, child, survey) in self._stops.get((camera, visit), []):
            if left <= 0:
                break
            n = min(left, len(world))
            left -= n
            seen = np.isfinite(world[:n]).all(axis=1) & np.isfinite(pixels[:n]).all(axis=1)
            if not seen.any():
                continue
            rows = np.repeat(seen, 3)
            net.stop(
                station,
                self.camera_keys.index(key),
                world[:n][seen],
                cov[: 3 * n, : 3 * n][np.ix_(rows, rows)],
                pixels[:n][seen],
                child,
                None if survey is None else survey[: 3 * n][rows],
            )
        group = tuple(range(first, len(net.leds)))
        self.calibrations.append((camera, visit))
        self.calibration_stops.append(group)
        return group


def network_from_log(
    messages: Iterable[Any],
    pixel_noise_px: float | Mapping[str, float] | None = None,
    *,
    cameras: str = "shared",
    child_creep_m: float = 0.0,
    control_points: Mapping[str, NDArray[np.float64]] | None = None,
) -> tuple[Network, NetworkIndex]:
    """The network of a run's log.

    Args:
        messages: the log's messages in file order (``LogContents.messages``).
        pixel_noise_px: the LED detector's pixel noise (px), one for all cameras or each
            camera's by name; default each camera's smallest calibration residual
            (``sigma_px``), which also holds the LEDs' own errors and so weighs the pixels
            a little low.
        cameras: one of :data:`CAMERA_MODES`.
        child_creep_m: how far a standing child may creep on each horizontal axis while the
            parent drives (``campaign.child_creep_m``), m: added to the covariance of a
            stand's later sightings, once per parent fix since it was placed.
        control_points: surveyed world coordinates (3,) of control points by name, m; those
            not named are adjusted like any other point.

    Raises:
        ValueError: an unknown camera mode.
        LogNetworkError: the log holds no CPS fix with its children's measurements (a log
            written before fixes recorded them), or no calibration.
    """
    if cameras not in CAMERA_MODES:
        raise ValueError(f"cameras must be one of {CAMERA_MODES}, got {cameras!r}")
    net = CampaignNetwork(child_creep_m, control_points)
    times: list[float] = []
    calibrations: list[dict[str, Any]] = []
    for m in messages:
        d = m.data
        if m.topic == PARENT_FIX:
            net.builder.station(float(d["yaw"]), _a(d["translation"]))
            times.append(float(d["timestamp"]))
            children = list(d.get("children", ()))
            level = _a(d.get("children_level", np.zeros((0, 3)))).reshape(-1, 3)
            if children and len(level) != len(children):
                raise LogNetworkError(
                    "the log's CPS fixes do not record the children's measurements (a log "
                    "written before they did); run the campaign again to adjust it"
                )
            cov = _a(d.get("children_covariance", np.zeros((0, 3, 3)))).reshape(-1, 3, 3)
            for child, p, c in zip(children, level, cov, strict=True):
                net.builder.sight_child(child, p, c)
        elif m.topic == CHILD_PLACED and times:
            net.builder.stand(d["child"], _a(d["point_level"]), _a(d["covariance"]), _a(d["world"]))
        elif m.topic == CONTROL_SIGHTING and times:
            net.builder.sight_control(d["name"], _a(d["point_level"]), _a(d["covariance"]))
        elif m.topic == POINT and d["dataset"] == "visit" and times:
            world = _a(d["leds_world"]).reshape(-1, 3)
            cov = _a(d.get("leds_covariance", np.zeros((0, 0))))
            if cov.size == 0:  # a log written before the points' covariance was recorded
                cov = np.zeros((3 * len(world), 3 * len(world)))
            survey = _a(d.get("survey_loading", np.zeros((0, 0))))
            net.stop(
                d["camera"],
                int(d["visit"]),
                world,
                cov,
                _a(d["pixels"]).reshape(-1, 2),
                str(d.get("child", "")),
                survey.reshape(len(survey), -1) if survey.size else None,
            )
        elif m.topic == CALIBRATION:
            calibrations.append(d)
    if not times or not calibrations:
        raise LogNetworkError("the log holds no CPS fix or no calibration to adjust")
    for rec in calibrations:
        net.calibrated(
            rec["camera"],
            int(rec["visit"]),
            camera_from_dict(rec["camera_model"], f"calibration of {rec['camera']}"),
            int(rec["points"]),
            _pixel_noise(pixel_noise_px, rec, calibrations),
            per_visit=cameras == "per_visit",
        )
    index = NetworkIndex(
        camera_keys=tuple(net.camera_keys),
        calibrations=tuple(net.calibrations),
        calibration_stops=tuple(net.calibration_stops),
        stations_time=tuple(times),
    )
    return net.builder.build(), index


def _pixel_noise(
    given: float | Mapping[str, float] | None, rec: dict[str, Any], every: list[dict[str, Any]]
) -> float:
    """The pixel noise of a calibration's camera (see :func:`network_from_log`)."""
    if isinstance(given, Mapping):
        if rec["camera"] in given:
            return float(given[rec["camera"]])
        given = None
    if given is not None:
        return float(given)
    own = [float(r["sigma_px"]) for r in every if r["camera"] == rec["camera"]]
    finite = [s for s in own if np.isfinite(s) and s > 0]
    if not finite:
        raise LogNetworkError(
            f"camera {rec['camera']!r}: no pixel noise given and no calibration residual to "
            "estimate it from"
        )
    return min(finite)
