"""The lens remap: a point of the pinhole render lands where the camera model projects it.

The pinhole renders here are drawn in numpy (no MuJoCo): small discs with their pixel
coverage integrated, so the only thing tested is the remap and the pixel integration.
"""

from __future__ import annotations

import numpy as np
import pytest

from calib.camera import TsaiCamera
from calib.opencv_camera import OpenCVCamera
from twin.scenario.schema import CameraConfig
from twin.sim.lens import lens_warp

SIZE = (320, 240)


def tsai(kappa1: float) -> TsaiCamera:
    return TsaiCamera.from_pose(
        f=770.0,
        cx=163.2,
        cy=117.9,
        kappa1=kappa1,
        sx=1.02,
        position=(0.0, 0.0, 0.0),
        view_direction=(1.0, 0.0, 0.0),
        image_size=SIZE,
    )


def opencv() -> OpenCVCamera:
    cam = tsai(0.0)
    k = np.array([[785.4, 0.0, 163.2], [0.0, 770.0, 117.9], [0.0, 0.0, 1.0]])
    return OpenCVCamera(
        k, np.array([-0.35, 0.2, 0.002, -0.001, 0.0]), cam.world2cam_r, cam.world2cam_t, SIZE
    )


def draw_discs(width, height, centres, radius, sub=8):
    """(height, width, 3) uint8 image, white discs on grey, edges anti-aliased by ``sub``."""
    img = np.full((height, width), 60.0)
    off = (np.arange(sub) + 0.5) / sub - 0.5
    for cu, cv in centres:
        u0, u1 = int(np.floor(cu - radius - 1)), int(np.ceil(cu + radius + 1))
        v0, v1 = int(np.floor(cv - radius - 1)), int(np.ceil(cv + radius + 1))
        for v in range(max(v0, 0), min(v1, height - 1) + 1):
            for u in range(max(u0, 0), min(u1, width - 1) + 1):
                du = u + off[None, :] - cu
                dv = v + off[:, None] - cv
                a = np.mean(du**2 + dv**2 <= radius**2)
                img[v, u] = a * 255.0 + (1.0 - a) * img[v, u]
    return np.repeat(np.rint(img)[:, :, None], 3, axis=2).astype(np.uint8)


def centroids(levels, expected, window=6):
    """Centroid of (levels - background) around each expected pixel."""
    g = levels.mean(axis=2) - 60.0
    out = []
    for u, v in expected:
        ui, vi = round(u), round(v)
        patch = np.clip(g[vi - window : vi + window + 1, ui - window : ui + window + 1], 0, None)
        vv, uu = np.mgrid[vi - window : vi + window + 1, ui - window : ui + window + 1]
        out.append([(patch * uu).sum() / patch.sum(), (patch * vv).sum() / patch.sum()])
    return np.array(out)


# Normalised image coordinates of test points: centre, edges and near the corners.
XY = np.array([[0.0, 0.0], [0.16, 0.11], [-0.16, 0.11], [0.16, -0.12], [-0.05, 0.11]])


@pytest.mark.parametrize(
    ("camera", "supersample"),
    [
        (tsai(4.33e-7), 1),  # the paper's camera 1: 3.5 px at the corners
        (tsai(4.0e-6), 1),  # ten times more: about 30 px at the corners
        (tsai(4.0e-6), 3),
        (tsai(-3.0e-6), 2),  # pincushion
        (opencv(), 2),
    ],
)
def test_points_land_on_the_projection(camera, supersample):
    warp = lens_warp(camera, supersample)
    view = warp.view
    # The pinhole render: discs at the view's pinhole pixels of the test points.
    centres = np.column_stack([view.fx * XY[:, 0] + view.cx, view.fy * XY[:, 1] + view.cy])
    radius = 2.0 * supersample
    pinhole = draw_discs(view.width, view.height, centres, radius)
    out = warp.apply(pinhole)
    assert out.shape == (SIZE[1], SIZE[0], 3)
    truth = camera.project(np.column_stack([XY * 5.0, np.full(len(XY), 5.0)]) @ camera.world2cam_r)
    # Where the lens really moves the points (up to ~30 px), they must follow it: the
    # residual is the disc's own distortion (its centroid is not its centre's image, a
    # few hundredths of a px) and interpolation.
    got = centroids(out, truth)
    np.testing.assert_allclose(got, truth, atol=0.05)


def test_margin_covers_every_undistorted_pixel():
    for camera in (tsai(4.0e-6), tsai(-3.0e-6), opencv()):
        warp = lens_warp(camera, 2)
        assert warp.map_x.min() >= 0.0
        assert warp.map_y.min() >= 0.0
        assert warp.map_x.max() <= warp.view.width - 1
        assert warp.map_y.max() <= warp.view.height - 1


def test_no_distortion_and_no_supersampling_is_the_render_itself():
    camera = tsai(0.0)
    warp = lens_warp(camera, 1)
    assert warp.map_x is None
    assert (warp.view.width, warp.view.height) == SIZE
    assert (warp.view.cx, warp.view.cy) == (camera.cx, camera.cy)
    img = np.random.default_rng(0).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    np.testing.assert_array_equal(warp.apply(img), img)


def test_supersampling_integrates_each_pixels_area():
    camera = tsai(0.0)
    warp = lens_warp(camera, 4)
    assert (warp.view.width, warp.view.height) == (1280, 960)
    # Fine pixel centres s*u + (s - 1)/2: the principal point keeps its place.
    assert warp.view.cx == pytest.approx(4 * camera.cx + 1.5)
    fine = np.zeros((960, 1280, 3), dtype=np.uint8)
    fine[0:2, 0:4] = 255  # half of output pixel (0, 0)
    out = warp.apply(fine)
    assert out[0, 0, 0] == pytest.approx(127.5)
    assert out[0, 1, 0] == 0.0


def test_bad_arguments():
    with pytest.raises(ValueError, match="supersample"):
        lens_warp(tsai(0.0), 0)
    with pytest.raises(ValueError, match="expected a 320x240 render"):
        lens_warp(tsai(0.0), 1).apply(np.zeros((10, 10, 3), dtype=np.uint8))


def test_the_scenario_and_the_renderer_refuse_a_folding_lens():
    with pytest.raises(ValueError, match="folds the image"):
        lens_warp(tsai(-1e-5))
    args = {
        "name": "c",
        "position": (0.0, 0.0, 2.0),
        "view_direction": (1.0, 0.0, -0.3),
        "f": 770.0,
        "cx": 160.0,
        "cy": 120.0,
        "image_size": (320, 240),
    }
    with pytest.raises(ValueError, match="folds the image"):
        CameraConfig(kappa1=-1e-5, **args)
    with pytest.raises(ValueError, match="not invertible"):
        CameraConfig(opencv_distortion=(-60.0, 0.0, 0.0, 0.0), **args)
