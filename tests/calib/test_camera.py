"""The Tsai camera model: projection, lines of sight, construction."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.camera import TsaiCamera
from calib.metrics import errors_3d, evaluate, pixel_errors
from calib.rotation import look_at_world2cam


def test_unproject_inverts_project(paper_cam, cam1_points) -> None:
    from calib.synthetic import led_points

    pts = led_points(paper_cam, 50, np.random.default_rng(3))
    uv = paper_cam.project(pts)
    origins, dirs = paper_cam.unproject(uv)
    assert_allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-12)
    assert_allclose(origins, np.broadcast_to(paper_cam.position, origins.shape), atol=1e-12)
    # Each point lies on its line of sight.
    assert_allclose(errors_3d(paper_cam, pts, uv), 0.0, atol=1e-9)


def test_pinhole_matches_opencv_projection(cam1, cam1_points) -> None:
    cam = cam1.with_(kappa1=0.0, sx=1.02)
    k = np.array([[cam.sx * cam.f, 0, cam.cx], [0, cam.f, cam.cy], [0, 0, 1]])
    rvec = cv2.Rodrigues(cam.world2cam_r)[0]
    uv_cv, _ = cv2.projectPoints(cam1_points, rvec, cam.world2cam_t, k, np.zeros(5))
    assert_allclose(cam.project(cam1_points), uv_cv.reshape(-1, 2), atol=1e-6)


@pytest.mark.parametrize(("kappa1", "scale"), [(4e-6, 1.05), (-4e-6, 0.95)])
def test_projection_of_a_known_point_by_hand(kappa1, scale) -> None:
    # Tsai's convention, worked by hand: the distorted point (x_d, y_d) = (100, -50) px
    # has r_d^2 = 12500 px^2, so its undistorted point is (x_d, y_d) (1 + kappa1 r_d^2) =
    # (100, -50) * scale. A camera at the origin looking along +z (OpenCV's frame: x
    # right, y down) sees it at (x_c, y_c) = (x_u, y_u) z / f, and puts its pixel at
    # u = sx x_d + cx = 1.02 * 100 + 160 = 262, v = y_d + cy = -50 + 120 = 70.
    cam = TsaiCamera(800.0, 160.0, 120.0, kappa1, 1.02, np.eye(3), np.zeros(3))
    z = 4.0
    point = np.array([[100.0 * scale * z / 800.0, -50.0 * scale * z / 800.0, z]])
    assert_allclose(cam.project(point), [[262.0, 70.0]], rtol=0, atol=1e-9)
    # The line of sight through that pixel passes through the point.
    origin, direction = cam.unproject([[262.0, 70.0]])
    assert_allclose(origin[0], 0.0, atol=1e-12)
    assert_allclose(direction[0], point[0] / np.linalg.norm(point[0]), atol=1e-12)


def test_centre_of_image_is_on_the_optical_axis(cam1) -> None:
    point = cam1.position + 7.0 * cam1.optical_axis
    assert_allclose(cam1.project(point[None]), [[cam1.cx, cam1.cy]], atol=1e-9)


def test_from_view_direction_is_upright() -> None:
    cam = TsaiCamera.from_pose(
        f=770.0, cx=159.5, cy=119.5, position=[0, 0, 2.5], view_direction=[0, 1, -0.36]
    )
    assert_allclose(cam.optical_axis, np.array([0, 1, -0.36]) / np.hypot(1, 0.36))
    # A point above the axis appears in the upper half of the image (v < cy).
    uv = cam.project([[0, 8, 3.0]])
    assert uv[0, 1] < cam.cy
    # A point to the right of the view direction appears right of the centre (u > cx).
    right = np.cross(cam.optical_axis, [0, 0, 1])
    uv = cam.project([cam.position + 5 * cam.optical_axis + right])
    assert uv[0, 0] > cam.cx


def test_points_behind_the_camera_are_rejected(cam1) -> None:
    behind = cam1.position - 3.0 * cam1.optical_axis
    with pytest.raises(ValueError, match=r"1 point\(s\) lie behind the camera, first in row 1"):
        cam1.project(np.vstack([cam1.position + cam1.optical_axis, behind]))


def test_invalid_camera_parameters() -> None:
    r = look_at_world2cam([1, 0, 0])
    with pytest.raises(ValueError, match="proper rotation"):
        TsaiCamera(770, 160, 120, 0, 1, -r, np.zeros(3))
    with pytest.raises(ValueError, match="positive"):
        TsaiCamera(-770, 160, 120, 0, 1, r, np.zeros(3))
    with pytest.raises(ValueError, match="kappa1 must be finite"):
        TsaiCamera(770, 160, 120, np.nan, 1, r, np.zeros(3))
    with pytest.raises(ValueError, match="exactly one"):
        TsaiCamera.from_pose(f=770, cx=1, cy=1, position=[0, 0, 0])
    with pytest.raises(ValueError, match="parallel to up"):
        look_at_world2cam([0, 0, -1])


def test_metrics_of_known_offsets(cam1, cam1_points) -> None:
    uv = cam1.project(cam1_points)
    shifted = uv + np.array([0.6, 0.8])  # 1 px everywhere
    assert_allclose(pixel_errors(cam1, cam1_points, shifted), 1.0, atol=1e-9)
    m = evaluate(cam1, cam1_points, shifted)
    assert m.pixel.mean == pytest.approx(1.0)
    assert m.pixel.max == pytest.approx(1.0)
    assert m.n_points == 70
    # Move each 3D point 5 mm perpendicular to its line of sight: 3D error 5 mm exactly.
    _, dirs = cam1.unproject(uv)
    perp = np.cross(dirs, [0.0, 0.0, 1.0])
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    assert_allclose(errors_3d(cam1, cam1_points + 5e-3 * perp, uv), 5e-3, atol=1e-10)


@pytest.mark.parametrize("kappa1", [0.0, 7.02e-7, -7.02e-7])
def test_analytic_jacobian_matches_finite_differences(paper_cam, kappa1) -> None:
    from calib.camera import project_tsai
    from calib.camera_jacobian import project_tsai_jacobian
    from calib.covariance import central_jacobian
    from calib.rotation import matrix2rotvec, right_jacobian, rotvec2matrix
    from calib.synthetic import led_points

    cam = paper_cam.with_(kappa1=kappa1, sx=1.01)
    pts = led_points(cam, 30, np.random.default_rng(0))
    q = np.concatenate(
        [
            [cam.f, cam.cx, cam.cy, cam.sx, cam.kappa1],
            matrix2rotvec(cam.world2cam_r),
            cam.position,
        ]
    )

    def pixels(x: np.ndarray) -> np.ndarray:
        r = rotvec2matrix(x[5:8])
        return project_tsai(pts, x[0], x[1], x[2], x[3], x[4], r, -r @ x[8:11]).ravel()

    steps = np.array([1e-3, 1e-3, 1e-3, 1e-6, 1e-12, 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5])
    numeric = central_jacobian(pixels, q, steps)
    r = rotvec2matrix(q[5:8])
    uv, jac = project_tsai_jacobian(pts, *q[:5], r, q[8:11], right_jacobian(q[5:8]))
    assert_allclose(uv, cam.project(pts), atol=1e-9)
    scale = np.abs(numeric).max(axis=0)
    assert_allclose(jac.reshape(-1, 11) / scale, numeric / scale, atol=1e-6)


def test_project_or_nan_is_project_for_each_point(paper_cam) -> None:
    rng = np.random.default_rng(11)
    ahead = paper_cam.optical_axis * rng.uniform(-5.0, 40.0, (400, 1))
    points = paper_cam.position + ahead + rng.normal(0.0, 4.0, (400, 3))
    folded = paper_cam.with_(kappa1=-2e-6)  # a fold inside the field of view
    for cam in (paper_cam, folded):
        batch = cam.project_or_nan(points)
        assert batch.shape == (400, 2)
        for p, uv in zip(points, batch, strict=True):
            try:
                alone = cam.project(p[None])[0]
            except ValueError:
                alone = np.full(2, np.nan)
            # Equal but for the rounding of the matrix product (one row or many).
            assert_allclose(uv, alone, rtol=1e-9, atol=0, equal_nan=True)
    assert np.isnan(folded.project_or_nan(points)).any()
    assert np.isnan(paper_cam.project_or_nan(points)).any()  # points behind the camera
