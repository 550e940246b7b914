"""The global adjustment: every measurement of a campaign in one least-squares problem.

The unknowns are the parent's stations (yaw and instrument centre, station 0 fixed: it is
W), the targets measured from more than one station (the children's stands, control
points) and each camera's Tsai parameters. The residuals, each whitened by its own
covariance so that a consistent network has unit variance:

- a target measured from a station: ``Rz(yaw)^T (X - t) - z`` (3 per sighting), with the
  total station's and inclinometer's covariance of ``z``;
- an LED stop: the detected pixels minus the camera's projection of ``Rz(yaw) l + t``,
  with the LEDs ``l`` as measured in the levelled frame. Their errors are shared by the
  LEDs of a stop (one marker pose), so each stop's pixel residuals get the joint covariance
  ``sigma_px^2 I + G Cov(l) G^T`` (``G`` the projection's derivative with respect to the
  LEDs), fixed at the start.

Where a child's marker assembly is known only to its survey (``LedSighting.survey_level``),
its survey error is an unknown too: a standard normal vector ``z`` (its prior, one residual
a component) that moves the LEDs of every stop of the child by ``S z``, turned with it.

Solved by Levenberg-Marquardt on the sparse normal equations ``J^T J``, each step solved
exactly by sparse LU (:func:`scipy.sparse.linalg.splu`): each residual touches one station
and one target or camera, so a hall campaign's Jacobian (a few thousand residuals, about
600 unknowns) has about 2 % of its entries non-zero. :func:`scipy.optimize.least_squares`
takes a sparse Jacobian only with its iterative trust-region solver (LSMR), which on this
problem's mixed scales (pixels and focal lengths of hundreds, radians, metres) stopped at
200 evaluations short of the minimum (8 s on the hall, both cores loaded); the direct
solve converges in 4 to 8 evaluations (0.07 s on an idle core). The parameters'
covariance is the inverse of ``J^T J`` at the solution (a priori: the weights are the
instruments' stated noise), solved by the same sparse LU for the columns asked for.

Without anything measured twice beyond the chain of CPS steps (a camera calibrated from
two stations, a control point) the adjusted stations are CPS's to first order; only the
cameras change, by the weighing of their LEDs' shared errors (which Tsai's calibration of
each visit leaves out). :func:`adjust_network` then raises :class:`NothingToAdjustError`
unless asked (``require_redundancy=False``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.linalg import splu
from scipy.stats import chi2 as chi2_dist

from calib.rotation import rot_z
from calib.tsai import N_TSAI, tsai_pixels_and_jacobian
from twin.localization.network import STATION_DOF, LedSighting, Network


class NothingToAdjustError(ValueError):
    """The network measured nothing twice: the adjustment would only repeat CPS."""


@dataclass(frozen=True, eq=False)
class AdjustedNetwork:
    """The adjusted network.

    Attributes:
        stations: (K, 4) adjusted (yaw rad, x, y, z m); row 0 is W's origin, as given.
        targets: (M, 3) adjusted targets, m.
        cameras: (C, 11) adjusted parameters (:func:`calib.tsai.tsai_vector`).
        camera_covariances: (C, 11, 11) their covariances.
        station_covariances: (K, 4, 4) of the stations (zero for station 0).
        chi2: sum of the squared whitened residuals at the solution. dof: residuals minus
            unknowns. evaluations: residual evaluations the solver made.
        redundancy: what the network measured twice, in words.
        surveys: each surveyed child's adjusted (M,) survey error, in units of its
            loadings (``LedSighting.survey_level``: standard normal a priori); its LEDs
            stand ``S z`` off where their stops placed them.
        survey_covariances: their (M, M) covariances.
    """

    stations: NDArray[np.float64]
    targets: NDArray[np.float64]
    cameras: NDArray[np.float64]
    camera_covariances: NDArray[np.float64]
    station_covariances: NDArray[np.float64]
    chi2: float
    dof: int
    evaluations: int
    redundancy: tuple[str, ...]
    surveys: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    survey_covariances: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    @property
    def variance_factor(self) -> float:
        """chi2 / dof: about 1 when the stated noise is right."""
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    def passes(self, false_alarm_rate: float) -> bool:
        """The global test: whether chi2 lies below the ``1 - false_alarm_rate`` quantile
        of the chi-square distribution with ``dof`` degrees of freedom (what the stated
        noise allows). A network with no redundancy passes."""
        return self.dof <= 0 or float(chi2_dist.sf(self.chi2, self.dof)) >= false_alarm_rate


class _Layout:
    """Where each unknown sits in the solver's vector."""

    def __init__(self, network: Network) -> None:
        self.n_stations = len(network.stations)
        counts = network.sightings_of_targets()
        self.free_targets = np.flatnonzero(~network.known_targets & (counts > 0))
        self.target_column = np.full(len(network.targets), -1)
        start = STATION_DOF * (self.n_stations - 1)
        self.target_column[self.free_targets] = start + 3 * np.arange(len(self.free_targets))
        self.camera_start = start + 3 * len(self.free_targets)
        self.camera_end = self.camera_start + N_TSAI * len(network.cameras)
        # Each surveyed child's (M,) standard normal survey error, after the cameras.
        widths: dict[str, int] = {}
        for s in network.led_sightings:
            if s.survey_level.size:
                widths.setdefault(s.child, s.survey_level.shape[1])
        self.survey_column: dict[str, int] = {}
        self.survey_width: dict[str, int] = {}
        at = self.camera_end
        for child in sorted(widths):
            self.survey_column[child], self.survey_width[child] = at, widths[child]
            at += widths[child]
        self.size = at

    def camera_column(self, c: int | NDArray[np.int64]) -> Any:
        """First column of camera ``c`` (or of each camera of an array)."""
        return self.camera_start + N_TSAI * c

    def pack(self, network: Network) -> NDArray[np.float64]:
        x = np.zeros(self.size)
        x[: self.camera_start - 3 * len(self.free_targets)] = network.stations[1:].ravel()
        for m in self.free_targets:
            x[self.target_column[m] : self.target_column[m] + 3] = network.targets[m]
        x[self.camera_start : self.camera_end] = network.cameras.ravel()
        return x  # the survey errors start at 0

    def unpack(self, x: NDArray[np.float64], network: Network) -> tuple[NDArray, NDArray, NDArray]:
        stations = network.stations.copy()
        stations[1:] = x[: STATION_DOF * (self.n_stations - 1)].reshape(-1, STATION_DOF)
        targets = network.targets.copy()
        for m in self.free_targets:
            targets[m] = x[self.target_column[m] : self.target_column[m] + 3]
        cameras = x[self.camera_start : self.camera_end].reshape(-1, N_TSAI)
        return stations, targets, cameras


def _whitener(covariance: NDArray[np.float64]) -> NDArray[np.float64]:
    """The inverse of the Cholesky factor: ``W C W^T = I``. A zero covariance (a noise-free
    simulation) gets a floor of 1e-20 (1e-10 of its units' std), a singular one 1e-12 of
    its largest variance."""
    floor = max(1e-12 * float(np.max(np.diag(covariance), initial=0.0)), 1e-20)
    n = len(covariance)
    return np.linalg.inv(np.linalg.cholesky(covariance + floor * np.eye(n)))


class _Problem:
    """Residuals and their sparse Jacobian, whitened by one block-diagonal matrix."""

    def __init__(self, network: Network) -> None:
        self.net = network
        self.layout = _Layout(network)
        ps = network.point_sightings
        self.p_station = np.array([s.station for s in ps], dtype=int)
        self.p_target = np.array([s.target for s in ps], dtype=int)
        self.p_z = np.array([s.point_level for s in ps]).reshape(-1, 3)
        leds = network.led_sightings
        counts = [len(s.pixels) for s in leds]
        self.l_station = np.repeat([s.station for s in leds], counts).astype(int)
        self.l_camera = np.repeat([s.camera for s in leds], counts).astype(int)
        self.l_level = np.concatenate([s.leds_level for s in leds]) if leds else np.zeros((0, 3))
        self.l_pixels = np.concatenate([s.pixels for s in leds]) if leds else np.zeros((0, 2))
        self._survey_loadings(leds)
        self.rows_points = 3 * len(ps)
        self.rows_prior = self.rows_points + 2 * len(self.l_level)
        n_survey = self.layout.size - self.layout.camera_end
        self.size = self.rows_prior + n_survey
        blocks = [_whitener(s.covariance) for s in ps] + self._led_whiteners()
        if n_survey:
            blocks.append(np.eye(n_survey))  # the survey errors' prior: standard normal
        self.whitener = sp.block_diag(blocks, format="csr") if blocks else sp.csr_matrix((0, 0))

    def _survey_loadings(self, leds: tuple[LedSighting, ...]) -> None:
        """Each LED's (3, M) loading on its child's survey error in the levelled frame and
        the (M,) columns of that error (-1: none, where the assembly is known exactly or
        the child's error has fewer than M components)."""
        width = max(self.layout.survey_width.values(), default=0)
        n = len(self.l_level)
        self.l_survey = np.zeros((n, 3, width))
        self.l_survey_columns = np.full((n, width), -1)
        at = 0
        for s in leds:
            k = len(s.pixels)
            if s.survey_level.size:
                m = s.survey_level.shape[1]
                if m != self.layout.survey_width[s.child]:
                    raise ValueError(
                        f"the stops of {s.child} load on {self.layout.survey_width[s.child]} "
                        f"and {m} survey components"
                    )
                self.l_survey[at : at + k, :, :m] = s.survey_level.reshape(k, 3, m)
                self.l_survey_columns[at : at + k, :m] = self.layout.survey_column[
                    s.child
                ] + np.arange(m)
            at += k

    def _survey_errors(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, M) each LED's child's survey error in ``x`` (zeros where known exactly)."""
        cols = self.l_survey_columns
        return np.where(cols >= 0, x[np.maximum(cols, 0)], 0.0)

    def _led_whiteners(self) -> list[NDArray[np.float64]]:
        """Each stop's whitener from its pixel noise and its LEDs' covariance, at the start."""
        out = []
        for s in self.net.led_sightings:
            yaw, t = self.net.stations[s.station, 0], self.net.stations[s.station, 1:]
            rot = rot_z(yaw)
            q = self.net.cameras[s.camera]
            size = tuple(int(v) for v in self.net.image_sizes[s.camera])
            _, jac = tsai_pixels_and_jacobian(q, s.leds_level @ rot.T + t, size)
            n = len(s.pixels)
            g = np.zeros((2 * n, 3 * n))
            for i in range(n):
                g[2 * i : 2 * i + 2, 3 * i : 3 * i + 3] = -jac[i, :, 8:11] @ rot
            cov = self.net.pixel_noise_px[s.camera] ** 2 * np.eye(2 * n)
            cov += g @ s.covariance_level @ g.T
            out.append(_whitener(0.5 * (cov + cov.T)))
        return out

    def _station_columns(self, stations: NDArray[np.int64]) -> NDArray[np.int64]:
        """(N, 4) columns of the stations' unknowns (negative for station 0)."""
        return STATION_DOF * (stations[:, None] - 1) + np.arange(STATION_DOF)[None, :]

    def residuals_and_jacobian(self, x: NDArray[np.float64]) -> tuple[NDArray, sp.csr_matrix]:
        stations, targets, cameras = self.layout.unpack(x, self.net)
        raw = np.zeros(self.size)
        rows: list[NDArray] = []
        cols: list[NDArray] = []
        vals: list[NDArray] = []

        def add(first_row: NDArray, block: NDArray, columns: NDArray) -> None:
            """Entries of (N, r, c) derivative blocks at rows ``first_row + (0..r-1)`` and
            (N, c) columns; negative columns (fixed unknowns) are left out."""
            n, r, c = block.shape
            rr = np.broadcast_to((first_row[:, None] + np.arange(r))[:, :, None], (n, r, c))
            cc = np.broadcast_to(columns[:, None, :], (n, r, c))
            keep = cc >= 0
            rows.append(rr[keep])
            cols.append(cc[keep])
            vals.append(block[keep])

        # Targets measured from stations: Rz(yaw)^T (X - t).
        yaw = stations[self.p_station, 0]
        c, s = np.cos(yaw), np.sin(yaw)
        d = targets[self.p_target] - stations[self.p_station, 1:]
        level = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])
        raw[: self.rows_points] = (level - self.p_z).ravel()
        rt = np.zeros((len(yaw), 3, 3))
        rt[:, 0, 0], rt[:, 0, 1], rt[:, 1, 0], rt[:, 1, 1], rt[:, 2, 2] = c, s, -s, c, 1.0
        d_yaw = np.column_stack([-s * d[:, 0] + c * d[:, 1], -c * d[:, 0] - s * d[:, 1], 0 * c])
        first = 3 * np.arange(len(yaw))
        add(
            first,
            np.concatenate([d_yaw[:, :, None], -rt], axis=2),
            self._station_columns(self.p_station),
        )
        target_cols = self.layout.target_column[self.p_target]
        add(first, rt, np.where(target_cols[:, None] >= 0, target_cols[:, None] + np.arange(3), -1))

        # LEDs seen by cameras: pixels - P(q, Rz(yaw) (l + S z) + t), S z the LEDs' share of
        # their child's survey error.
        yaw = stations[self.l_station, 0]
        c, s = np.cos(yaw), np.sin(yaw)
        lv = self.l_level + np.einsum("nim,nm->ni", self.l_survey, self._survey_errors(x))
        world = (
            np.column_stack([c * lv[:, 0] - s * lv[:, 1], s * lv[:, 0] + c * lv[:, 1], lv[:, 2]])
            + stations[self.l_station, 1:]
        )
        d_world_d_yaw = np.column_stack(
            [-s * lv[:, 0] - c * lv[:, 1], c * lv[:, 0] - s * lv[:, 1], 0 * c]
        )
        uv = np.zeros((len(lv), 2))
        jac = np.zeros((len(lv), 2, N_TSAI))
        for cam in np.unique(self.l_camera):
            mine = self.l_camera == cam
            size = tuple(int(v) for v in self.net.image_sizes[cam])
            uv[mine], jac[mine] = tsai_pixels_and_jacobian(cameras[cam], world[mine], size)
        raw[self.rows_points : self.rows_prior] = np.nan_to_num(uv - self.l_pixels, nan=1e3).ravel()
        jac = np.nan_to_num(jac, nan=0.0)
        first = self.rows_points + 2 * np.arange(len(lv))
        cam_cols = self.layout.camera_column(self.l_camera)[:, None] + np.arange(N_TSAI)
        add(first, jac, cam_cols)
        d_world = -jac[:, :, 8:11]
        d_station = np.concatenate(
            [np.einsum("nij,nj->ni", d_world, d_world_d_yaw)[:, :, None], d_world], axis=2
        )
        add(first, d_station, self._station_columns(self.l_station))
        if self.l_survey.shape[2]:
            turn = np.zeros((len(lv), 3, 3))
            turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1] = c, -s, s, c
            turn[:, 2, 2] = 1.0
            d_survey = np.einsum("nij,njk,nkm->nim", d_world, turn, self.l_survey)
            add(first, d_survey, self.l_survey_columns)
            # The prior of the survey errors: z itself (standard normal).
            z = x[self.layout.camera_end :]
            raw[self.rows_prior :] = z
            prior = np.arange(len(z))
            add(
                self.rows_prior + prior,
                np.ones((len(z), 1, 1)),
                (self.layout.camera_end + prior)[:, None],
            )

        jac_raw = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.size, self.layout.size),
        )
        return self.whitener @ raw, (self.whitener @ jac_raw).tocsr()


def adjust_network(network: Network, *, require_redundancy: bool = True) -> AdjustedNetwork:
    """Adjust every station, target and camera of a network at once.

    Args:
        network: the measurements, started from the sequential estimates.
        require_redundancy: refuse a network that measured nothing twice.

    Returns:
        The adjusted network with its covariances.

    Raises:
        NothingToAdjustError: nothing was measured twice (no camera calibrated from two
            stations, no control point measured again or surveyed), and
            ``require_redundancy``.
        ValueError: more unknowns than residuals.
    """
    redundancy = network.redundancy()
    if require_redundancy and not redundancy:
        raise NothingToAdjustError(
            "nothing was measured twice (no camera calibrated from two stations, no control "
            "point measured again or surveyed): the adjustment would only repeat CPS"
        )
    problem = _Problem(network)
    if problem.size < problem.layout.size:
        raise ValueError(
            f"the network has {problem.layout.size} unknowns and only {problem.size} residuals"
        )
    x, evaluations = _levenberg_marquardt(problem, problem.layout.pack(network))
    res, jac = problem.residuals_and_jacobian(x)
    stations, targets, cameras = problem.layout.unpack(x, network)
    cov_cam, cov_st, cov_survey = _covariances(jac, problem.layout, len(network.cameras))
    layout = problem.layout
    surveys = {
        child: x[col : col + layout.survey_width[child]].copy()
        for child, col in layout.survey_column.items()
    }
    return AdjustedNetwork(
        stations=stations,
        targets=targets,
        cameras=cameras.copy(),
        camera_covariances=cov_cam,
        station_covariances=cov_st,
        chi2=float(res @ res),
        dof=int(problem.size - problem.layout.size),
        evaluations=evaluations,
        redundancy=tuple(redundancy),
        surveys=surveys,
        survey_covariances=cov_survey,
    )


def _levenberg_marquardt(
    problem: _Problem, x: NDArray[np.float64], max_iterations: int = 50
) -> tuple[NDArray[np.float64], int]:
    """Levenberg-Marquardt on the sparse normal equations, solved exactly (sparse LU).

    Returns the solution and the number of residual evaluations."""
    res, jac = problem.residuals_and_jacobian(x)
    cost = float(res @ res)
    damping = 1e-6
    evaluations = 1
    for _ in range(max_iterations):
        normal = (jac.T @ jac).tocsc()
        gradient = jac.T @ res
        scale = normal.diagonal()
        scale = np.where(scale > 0, scale, 1.0)
        while True:
            step = -splu((normal + sp.diags(damping * scale)).tocsc()).solve(gradient)
            trial = x + step
            res_t, jac_t = problem.residuals_and_jacobian(trial)
            evaluations += 1
            cost_t = float(res_t @ res_t)
            if np.isfinite(cost_t) and cost_t <= cost:
                break
            damping *= 10.0
            if damping > 1e10:
                return x, evaluations
        x, res, jac = trial, res_t, jac_t
        converged = cost - cost_t <= 1e-10 * max(cost, 1.0)
        cost = cost_t
        damping = max(damping / 10.0, 1e-9)
        if converged:
            break
    return x, evaluations


def _covariances(
    jac: sp.csr_matrix, layout: _Layout, n_cameras: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """(C, 11, 11) camera, (K, 4, 4) station and each child's (M, M) survey blocks of
    ``(J^T J)^-1``."""
    normal = (jac.T @ jac).tocsc()
    lu = splu(normal)
    cam_cols = layout.camera_start + np.arange(N_TSAI * n_cameras)
    st_cols = np.arange(STATION_DOF * (layout.n_stations - 1))
    survey_cols = np.arange(layout.camera_end, layout.size)
    cols = np.concatenate([cam_cols, st_cols, survey_cols])
    rhs = np.zeros((layout.size, len(cols)))
    rhs[cols, np.arange(len(cols))] = 1.0
    inv = lu.solve(rhs)
    cam = np.zeros((n_cameras, N_TSAI, N_TSAI))
    for c in range(n_cameras):
        idx = layout.camera_start + N_TSAI * c + np.arange(N_TSAI)
        local = N_TSAI * c + np.arange(N_TSAI)
        cam[c] = inv[np.ix_(idx, local)]
    stations = np.zeros((layout.n_stations, STATION_DOF, STATION_DOF))
    for k in range(1, layout.n_stations):
        idx = STATION_DOF * (k - 1) + np.arange(STATION_DOF)
        local = len(cam_cols) + idx
        stations[k] = inv[np.ix_(idx, local)]
    surveys = {}
    first = len(cam_cols) + len(st_cols) - layout.camera_end
    for child, col in layout.survey_column.items():
        idx = col + np.arange(layout.survey_width[child])
        block = inv[np.ix_(idx, first + idx)]
        surveys[child] = 0.5 * (block + block.T)
    return 0.5 * (cam + cam.transpose(0, 2, 1)), stations, surveys
