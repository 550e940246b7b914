"""Make ``camera1_points.csv``: 70 LED points seen by a synthetic camera like the paper's camera 1.

The camera takes the paper's Table II values for camera 1 (see ``calib.synthetic``). A child
robot with LEDs at four heights stands at random places in the camera's view; the 3D points
carry total-station noise (2 mm per axis) and the pixels LED-detection noise (0.3 px).
The true camera is written beside the points as ``camera1_truth.json``.

Run: ``python examples/make_camera1_points.py`` (seeded: the output is always the same).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.io import save_camera, write_points_csv
from calib.synthetic import led_points, paper_camera

SEED = 20070101
HERE = Path(__file__).parent


def main() -> None:
    rng = np.random.default_rng(SEED)
    camera = paper_camera(1)
    points = led_points(camera, 70, rng)
    pixels = camera.project(points) + rng.normal(0.0, 0.3, (len(points), 2))
    measured = points + rng.normal(0.0, 2e-3, points.shape)
    write_points_csv(HERE / "camera1_points.csv", measured, pixels, units="mm")
    save_camera(camera, HERE / "camera1_truth.json")


if __name__ == "__main__":
    main()
