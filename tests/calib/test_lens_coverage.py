"""A lens model that folds inside the image is refused, where it is made and where used."""

from __future__ import annotations

import math

import numpy as np

from calib.camera import TsaiCamera
from calib.lens_coverage import lens_fold_problem
from calib.opencv_camera import OpenCVCamera
from calib.synthetic import paper_camera


def tsai(kappa1: float) -> TsaiCamera:
    return paper_camera(1).with_(kappa1=kappa1)


def opencv(dist) -> OpenCVCamera:
    k = np.array([[770.0, 0.0, 160.0], [0.0, 770.0, 120.0], [0.0, 0.0, 1.0]])
    return OpenCVCamera(k, np.asarray(dist, dtype=float), image_size=(320, 240))


def test_real_lenses_are_one_to_one():
    for cam in (tsai(4.33e-7), tsai(-4.33e-7), tsai(3e-6), tsai(0.0)):
        assert lens_fold_problem(cam) is None
    assert lens_fold_problem(opencv([-0.3, 0.1, 0.001, -0.001, 0.0])) is None


def test_tsai_fold_inside_the_image():
    cam = tsai(-1e-5)  # folds 183 px from the centre; the corners are about 200 px away
    problem = lens_fold_problem(cam)
    assert problem is not None
    assert f"{1 / math.sqrt(3e-5):.1f} px" in problem
    # Just inside the corners: still one-to-one.
    du = max(abs(-0.5 - cam.cx), abs(319.5 - cam.cx)) / cam.sx
    dv = max(abs(-0.5 - cam.cy), abs(239.5 - cam.cy))
    corner = math.hypot(du, dv)
    assert lens_fold_problem(tsai(-0.99 / (3 * corner**2))) is None
    assert lens_fold_problem(tsai(-1.01 / (3 * corner**2))) is not None


def test_opencv_fold_inside_the_image():
    problem = lens_fold_problem(opencv([-60.0, 0.0, 0.0, 0.0, 0.0]))
    assert problem is not None
    assert "not invertible" in problem
