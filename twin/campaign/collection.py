"""A camera's data (paper Section II.A and Fig. 3): the child stops where its strategy
planned, the standing parent measures its prisms, the camera finds its LEDs; then the
camera is calibrated with Tsai's model.

A stop that gives no point (no heading shows the prisms, the child cannot get there, its
prisms are not measured, not every LED is found) is counted as a failure and replaced by
the plan's next spare stop. A data set whose stops reach their bound
(:func:`twin.campaign.bounds.stops_bound`) ends with the failure ``no_progress`` and the
points it has. Where the plan says so (:attr:`twin.campaign.strategy.StopPlan.
partial`: stops chosen for accuracy) a stop where some LEDs are found gives a point with
those (the missing LEDs' failures still counted).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from calib.detection.sequence import SwitchingSequence
from calib.io.camera_files import camera_to_dict
from calib.tsai import calibrate_tsai
from twin.campaign.bounds import stops_bound
from twin.campaign.journal import Journal
from twin.campaign.records import CalibrationRecord, DataPoint
from twin.campaign.strategy import PlannedStop, StopPlan
from twin.campaign.travel import Travel
from twin.hal.rig import Rig
from twin.instruments.marker_pose import led_positions, survey_loading
from twin.scenario.schema import CampaignSettings
from twin.timing import timed


class DataCollection:
    """Takes cameras' data and calibrates them.

    Args:
        rig: the devices. travel: moves and places the child.
        journal: the campaign's journal. settings: the campaign's settings.
        sequence: how the LEDs are switched for the cameras.
    """

    def __init__(
        self,
        rig: Rig,
        travel: Travel,
        journal: Journal,
        settings: CampaignSettings,
        sequence: SwitchingSequence,
    ) -> None:
        self.rig, self.travel, self.journal = rig, travel, journal
        self.settings = settings
        self.sequence = sequence

    def collect(
        self, camera: str, dataset: str, visit: int, target: int, plan: StopPlan
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[DataPoint]]:
        """LED points of ``camera`` at the plan's stops until ``target`` points.

        Args:
            camera: the camera. dataset: ``reference`` or ``visit``.
            visit: the camera's visit number (0 for a reference set).
            target: LED points wanted. plan: where the child stops.

        Returns:
            (N, 3) LED points in W, m; (N, 2) their pixels; the data points.
        """
        child = plan.child
        if plan.empty:
            self.journal.failure(
                "no_view_stops", "no place in the view for the child", child, camera
            )
            return np.zeros((0, 3)), np.zeros((0, 2)), []
        points: list[DataPoint] = []
        taken = 0
        most = stops_bound(target, self.settings.progress_slack)
        for count in range(most + 1):
            if taken >= target:
                break
            with timed(self.rig.timings, "planning"):
                planned = plan.next()
            if planned is None:
                break
            if count == most:
                what = f"stops for {camera}'s {dataset} data ({taken} of {target} points)"
                self.travel.no_progress(what, count, most, child, camera)
                break
            self.journal.show(robot=child, camera=camera, points=taken)
            point = self._point_at(planned, child, camera, dataset, visit, plan.partial)
            if point is None:
                plan.replace()
                continue
            self.journal.point(point)
            points.append(point)
            taken += len(point.leds_world)
        self.journal.show(points=taken)
        n = min(target, taken)
        self.journal.dataset(dataset, camera, visit, n)
        pts = np.array([p for point in points for p in point.leds_world]).reshape(-1, 3)
        pix = np.array([p for point in points for p in point.pixels]).reshape(-1, 2)
        return pts[:n], pix[:n], points

    def _point_at(
        self,
        planned: PlannedStop,
        child: str,
        camera: str,
        dataset: str,
        visit: int,
        partial: bool,
    ) -> DataPoint | None:
        """The child at one stop: its LEDs in W and in the image (those found, where
        ``partial``), or None (the failure recorded)."""
        if planned.yaw is None:
            self.journal.failure("prisms_hidden", "every heading hides a prism", child, camera)
            return None
        why = self.travel.drive_clear(child, planned.stop.xy, planned.yaw)
        if why:
            x, y = (float(v) for v in planned.stop.xy)
            where = f"stop ({x:.2f}, {y:.2f}) m"
            self.journal.failure("point_unreachable", f"{where}: {why}", child, camera, stop=[x, y])
            return None
        obs = self.travel.place_child_turning(child)
        if obs is None:
            message = "the child's prisms were not measured"
            self.journal.failure("point_skipped", message, child, camera)
            return None
        seen = self.rig.led_sensors[camera].observe(child, self.sequence)
        if not seen.complete:
            kinds = sorted({f for f in seen.failures if f is not None})
            # An LED the stop was planned without is not a failure where it is not found.
            planned_leds = planned.stop.leds
            missed = sorted(
                {
                    f
                    for k, f in enumerate(seen.failures)
                    if f is not None and (planned_leds is None or k in planned_leds)
                }
            )
            for kind in missed:
                self.journal.failure(f"led_{kind}", f"LEDs {kind}", child, camera)
            if not (partial and seen.found.any()):
                message = "not all LEDs found: " + ", ".join(kinds)
                self.journal.failure("point_skipped", message, child, camera)
                return None
        assert obs.marker_pose is not None
        parent = self.travel.cps.parent
        leds_level, cov_level = led_positions(obs.marker_pose, self.travel.marker)
        # Levelled frame to W turns about z: each LED's 3 x 3 block turns with it.
        turn = np.kron(np.eye(len(leds_level)), parent.rotation)
        leds_world = parent.level2world(leds_level)
        pixels = seen.pixels
        cov = turn @ cov_level @ turn.T
        marker = self.travel.marker
        survey = (
            survey_loading(marker, parent.rotation @ obs.marker_pose.rotation)
            if marker.survey_sigma > 0
            else np.zeros((0, 0))
        )
        if partial and not seen.complete:
            # The LEDs that were found, and their rows and columns of the joint covariance.
            found = seen.found
            rows = np.repeat(found, 3)
            leds_world, pixels, cov = leds_world[found], pixels[found], cov[np.ix_(rows, rows)]
            survey = survey[rows] if survey.size else survey
        return DataPoint(
            self.rig.clock.now(),
            dataset,
            camera,
            visit,
            child,
            leds_world,
            pixels,
            parent.level2world(obs.point_level)[:2],
            cov,
            partial,
            survey,
        )

    def calibrate(self, camera: str, visit: int, station: NDArray[np.float64], plan: StopPlan):
        """Take a visit's data and calibrate the camera (Tsai), or record why not."""
        pts, pix, _ = self.collect(camera, "visit", visit, self.settings.station_points, plan)
        if len(pts) < self.settings.min_points:
            message = f"{len(pts)} points, {self.settings.min_points} needed"
            self.journal.skipped(camera, visit, station, "too_few_points", message)
            return
        size = self.rig.led_sensors[camera].image_size
        try:
            with timed(self.rig.timings, "solving"):
                result = calibrate_tsai(pts, pix, size)
        except ValueError as exc:
            self.journal.failure("calibration_failed", str(exc), camera=camera)
            self.journal.skipped(camera, visit, station, "calibration_failed", str(exc))
            return
        self.journal.calibration(
            CalibrationRecord(
                timestamp=self.rig.clock.now(),
                camera=camera,
                visit=visit,
                station=station,
                distance_travelled=self.journal.travelled,
                points=len(pts),
                parameters=result.parameters,
                std=result.std_by_name,
                camera_model=camera_to_dict(result.camera),
                sigma_px=result.sigma_px,
            )
        )
