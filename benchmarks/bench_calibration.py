"""Calibration speed and accuracy: Tsai (ours) against cv2.calibrateCamera.

On the same synthetic data sets (the paper's three cameras, 70 LED points at four heights,
Gaussian pixel noise), both calibrate from the same start (the intrinsics of Tsai's
closed-form stages). Printed per camera: time per calibration of each, the ratio, and the
RMS error against the truth of the parameters both models share (f, cx, cy, camera position,
rotation). cv2 is timed on its calibrateCamera call alone; ours includes the closed-form
stages, the full optimisation, the covariance and the metrics.

Run: ``.venv/bin/python benchmarks/bench_calibration.py [--trials N] [--noise PX]``
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np
from rich.console import Console
from rich.table import Table

from calib import calibrate_tsai
from calib.rotation import rotation_angle_between
from calib.synthetic import led_points, paper_camera
from calib.tsai_linear import tsai_initial_estimate


def cv2_calibrate(pts: np.ndarray, uv: np.ndarray, size: tuple[int, int]) -> tuple:
    """cv2.calibrateCamera from the intrinsics of Tsai's closed-form stages; timed alone."""
    init = tsai_initial_estimate(pts, uv, size)
    k0 = np.array([[init.sx * init.f, 0, init.cx], [0, init.f, init.cy], [0, 0, 1.0]])
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3
    t0 = time.perf_counter()
    _, k, _, rvecs, tvecs = cv2.calibrateCamera(
        [pts.astype(np.float32)], [uv.astype(np.float32)], size, k0, np.zeros(5), flags=flags
    )
    dt = time.perf_counter() - t0
    r = cv2.Rodrigues(rvecs[0])[0]
    return dt, k[1, 1], k[0, 2], k[1, 2], -r.T @ tvecs[0].ravel(), r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--noise", type=float, default=0.3, help="pixel noise, px")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    console = Console(width=150)
    table = Table(
        title=f"Tsai (ours) vs cv2.calibrateCamera: 70 points, {args.noise} px noise, "
        f"{args.trials} trials per camera"
    )
    for col in (
        "camera", "method", "ms / calib", "time ratio", "f RMS [px]", "cx RMS [px]",
        "cy RMS [px]", "pos RMS [mm]", "rot RMS [deg]",
    ):  # fmt: skip
        table.add_column(col, justify="right")
    for index in (1, 2, 3):
        cam = paper_camera(index)
        rng = np.random.default_rng(args.seed + index)
        pts = led_points(cam, 70, rng)
        uv_true = cam.project(pts)
        rows: dict[str, list] = {"tsai": [], "cv2": []}
        for _ in range(args.trials):
            uv = uv_true + rng.normal(0.0, args.noise, uv_true.shape)
            t0 = time.perf_counter()
            res = calibrate_tsai(pts, uv, cam.image_size)
            dt = time.perf_counter() - t0
            c = res.camera
            rows["tsai"].append((dt, c.f, c.cx, c.cy, c.position, c.world2cam_r))
            rows["cv2"].append(cv2_calibrate(pts, uv, cam.image_size))
        times = {m: np.median([r[0] for r in v]) for m, v in rows.items()}
        for method, v in rows.items():
            f = np.array([r[1] for r in v]) - cam.f
            cx = np.array([r[2] for r in v]) - cam.cx
            cy = np.array([r[3] for r in v]) - cam.cy
            pos = np.array([np.linalg.norm(r[4] - cam.position) for r in v])
            rot = np.array([rotation_angle_between(r[5], cam.world2cam_r) for r in v])

            def rms(e: np.ndarray) -> float:
                return float(np.sqrt(np.mean(e**2)))

            table.add_row(
                str(index),
                "Tsai (ours)" if method == "tsai" else "cv2.calibrateCamera",
                f"{times[method] * 1e3:.2f}",
                f"{times[method] / times['cv2']:.2f}",
                f"{rms(f):.3f}",
                f"{rms(cx):.3f}",
                f"{rms(cy):.3f}",
                f"{rms(pos) * 1e3:.2f}",
                f"{np.degrees(rms(rot)):.4f}",
            )
    console.print(table)
    console.print(
        "time ratio: median time per calibration / median time of cv2.calibrateCamera "
        "in the same run. Position and rotation errors are norms (3D distance, angle)."
    )


if __name__ == "__main__":
    main()
