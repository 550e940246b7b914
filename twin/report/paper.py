"""The paper's published results as data (Yokoya, Hasegawa, Kurazume, Section IV).

Section IV ("Experiments") calibrates three cameras in a 60 m x 15 m x 8 m entrance hall
while the robot group travels about 85 m, visiting camera 1, 2, 3, 2 and 1 in that order.
It publishes:

* Table II, the calibrated parameters of the five calibrations: focal length / pixel size
  and image centre (px), kappa1, the camera's position (mm) and its rotation about the
  world X, Y and Z axes (deg);
* Table III, the mean pixel and 3D errors of the calibrations of cameras 1 and 2, in the
  world frame (against 70-point reference sets measured from the origin) and in the local
  frame (against the data of each calibration);
* in the text, the repeatability: the second calibrated position of camera 1 minus the
  first, (37.7, 18.9, -1.1) mm, and of camera 2, (39.0, -24.57, -10.56) mm.

Reading of Table II. The table as we have it is garbled: its row labels are shifted by
one, so the row labelled "X-axis [mm]" under kappa1 holds the kappa1 values, the row
labelled "Y-axis" the positions' X, "Z-axis" the positions' Y, and the row labelled
"position X-axis" the positions' Z (about 2.1 m: the cameras hang 2.5 m above a floor
0.4 m below the instrument). This module stores the corrected reading. Camera 1's X
difference in the text (37.7 mm) disagrees by 1 mm with the table's positions
(-3318.4 - -3355.1 = 36.7 mm); both are kept as published.

kappa1 is labelled 1/mm^2 in the paper; this project reads the numbers in 1/px^2 (see
``scenarios/paper_hall.toml`` and :mod:`calib.synthetic`). The rotation angles of cameras
1 and 2 are given here as published; the twin's scenario flips the sign of their X angle
(a sign the table lost, see ``scenarios/paper_hall.toml``).

Visits are keyed by (camera name, visit number): the scenario ``paper_hall`` names the
cameras ``cam1``, ``cam2``, ``cam3``, and the visit number counts the visits of one camera
(1 for the first, 2 for the second).
"""

from __future__ import annotations

from dataclasses import dataclass

ROUTE_LENGTH_M = 85.0
"""Total travelling distance of the parent robot, m (Section IV: "approximately 85 m")."""

REFERENCE_POINTS = 70
"""Points in each reference data set (cameras 1 and 2, measured from the origin)."""


@dataclass(frozen=True)
class PaperCalibration:
    """One column of Table II, in the paper's units.

    Attributes:
        camera: camera name in the twin (``cam1``...).
        visit: visit number of this camera (1 or 2).
        label: the paper's column heading.
        f_px: focal length / pixel size, px.
        cx, cy: image centre, px.
        kappa1: first-order radial distortion as published (labelled 1/mm^2; read as
            1/px^2 by this project).
        position_mm: (X, Y, Z) of the camera in the world frame, mm.
        rotation_deg: rotation about the world X, Y, Z axes, deg (as published).
    """

    camera: str
    visit: int
    label: str
    f_px: float
    cx: float
    cy: float
    kappa1: float
    position_mm: tuple[float, float, float]
    rotation_deg: tuple[float, float, float]

    @property
    def key(self) -> tuple[str, int]:
        """(camera, visit)."""
        return (self.camera, self.visit)


@dataclass(frozen=True)
class PaperErrors:
    """One column of Table III: mean errors of a calibration.

    Attributes:
        camera: camera name in the twin.
        visit: visit number of this camera.
        label: the paper's column heading.
        world_pixel: mean pixel error against the reference set (world frame), px.
        world_3d_mm: mean 3D error against the reference set (world frame), mm.
        local_pixel: mean pixel error on the calibration's own data (local frame), px.
        local_3d_mm: mean 3D error on the calibration's own data (local frame), mm.
    """

    camera: str
    visit: int
    label: str
    world_pixel: float
    world_3d_mm: float
    local_pixel: float
    local_3d_mm: float

    @property
    def key(self) -> tuple[str, int]:
        """(camera, visit)."""
        return (self.camera, self.visit)


TABLE_II: tuple[PaperCalibration, ...] = (
    PaperCalibration(
        "cam1", 1, "1 (1st)", 770.3, 160.0, 120.1, 4.33e-7,
        (-3355.1, 10625.5, 2117.4), (115.5, -2.9, 178.2),
    ),
    PaperCalibration(
        "cam2", 1, "2 (1st)", 761.8, 170.3, 109.1, 8.08e-8,
        (12506.6, -1101.1, 2079.2), (-112.4, 2.9, -1.6),
    ),
    PaperCalibration(
        "cam3", 1, "3", 754.2, 159.9, 120.0, 7.02e-7,
        (42900.6, 9298.2, 2075.6), (-123.5, 2.6, -173.5),
    ),
    PaperCalibration(
        "cam2", 2, "2 (2nd)", 770.4, 142.6, 111.9, 1.98e-7,
        (12545.6, -1125.7, 2068.7), (-112.6, 0.7, -1.7),
    ),
    PaperCalibration(
        "cam1", 2, "1 (2nd)", 763.9, 154.7, 115.4, 2.82e-7,
        (-3318.4, 10644.4, 2116.3), (115.6, -2.7, 178.1),
    ),
)  # fmt: skip
"""Table II, the five calibrations in the order of the visits."""

TABLE_III: tuple[PaperErrors, ...] = (
    PaperErrors("cam1", 1, "1 (1st)", 1.02, 7.53, 0.62, 4.39),
    PaperErrors("cam2", 1, "2 (1st)", 1.33, 11.47, 0.81, 6.54),
    PaperErrors("cam2", 2, "2 (2nd)", 4.04, 32.35, 0.75, 6.20),
    PaperErrors("cam1", 2, "1 (2nd)", 8.54, 60.24, 0.66, 4.69),
)
"""Table III, the calibrations of cameras 1 and 2 in the order of the visits."""

REPEATABILITY_MM: dict[str, tuple[float, float, float]] = {
    "cam1": (37.7, 18.9, -1.1),
    "cam2": (39.0, -24.57, -10.56),
}
"""Second calibrated position minus the first, mm, as given in the text of Section IV."""


def table_ii(camera: str, visit: int) -> PaperCalibration | None:
    """The Table II column of a (camera, visit), or None if the paper has none."""
    for col in TABLE_II:
        if col.key == (camera, visit):
            return col
    return None


def table_iii(camera: str, visit: int) -> PaperErrors | None:
    """The Table III column of a (camera, visit), or None if the paper has none."""
    for col in TABLE_III:
        if col.key == (camera, visit):
            return col
    return None
