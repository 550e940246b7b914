"""Tsai's model for T cameras at once equals the model of one camera, trial by trial, bit for
bit: both are the same computation."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from calib.camera import TsaiCameras
from calib.camera_jacobian import project_tsai_jacobian
from calib.rotation import (
    matrix2rotvec,
    right_jacobian,
    right_jacobian_batch,
    rotvec2matrix,
    rotvec2matrix_batch,
)
from calib.synthetic import led_points, paper_camera


@pytest.fixture(scope="module")
def three():
    """The paper's three cameras (one with sx != 1, one with a negative kappa1) and 40
    LED points in view of each."""
    cams = [
        paper_camera(1).with_(sx=1.013),
        paper_camera(2, kappa1=-1e-6),
        paper_camera(3),
    ]
    rng = np.random.default_rng(3)
    return cams, np.stack([led_points(c, 40, rng) for c in cams])


def test_rotations_of_a_stack_equal_those_of_each_vector() -> None:
    rng = np.random.default_rng(0)
    w = rng.normal(size=(6, 4, 3))
    w[0, 0] *= 1e-8  # the series branch
    w[1, 1] = 0.0
    w[2, 2] *= np.pi / np.linalg.norm(w[2, 2])
    r, j = rotvec2matrix_batch(w), right_jacobian_batch(w)
    assert r.shape == j.shape == (6, 4, 3, 3)
    for i in np.ndindex(w.shape[:2]):
        assert_allclose(r[i], rotvec2matrix(w[i]), rtol=0, atol=1e-15)
        assert_allclose(j[i], right_jacobian(w[i]), rtol=0, atol=1e-15)


def test_projection_and_lines_of_sight_equal_each_camera(three) -> None:
    cams, points = three
    batch = TsaiCameras.from_cameras(cams)
    uv = batch.project_or_nan(points)
    origins, dirs = batch.unproject(uv)
    for k, cam in enumerate(cams):
        assert_array_equal(uv[k], cam.project(points[k]))
        o, d = cam.unproject(uv[k])
        assert_array_equal(origins[k], o)
        assert_array_equal(dirs[k], d)
        assert batch.camera(k) == cam
    from_centres = TsaiCameras(*(getattr(batch, n) for n in ("f", "cx", "cy", "kappa1", "sx")),
                               batch.world2cam_r, batch.position, batch.image_size)  # fmt: skip
    assert_allclose(from_centres.world2cam_t, batch.world2cam_t, rtol=0, atol=1e-12)


def test_a_point_behind_its_camera_projects_to_nan(three) -> None:
    cams, points = three
    batch = TsaiCameras.from_cameras(cams)
    behind = points.copy()
    behind[1, 0] = 2 * cams[1].position - points[1, 0]
    uv = batch.project_or_nan(behind)
    assert np.isnan(uv[1, 0]).all()
    assert np.isfinite(np.delete(uv.reshape(-1, 2), 40, axis=0)).all()


def test_jacobian_equals_that_of_each_camera(three) -> None:
    cams, points = three
    batch = TsaiCameras.from_cameras(cams)
    rotvecs = np.stack([matrix2rotvec(c.world2cam_r) for c in cams])
    drot = right_jacobian_batch(rotvecs)
    uv, jac = project_tsai_jacobian(
        points, batch.f, batch.cx, batch.cy, batch.sx, batch.kappa1,
        batch.world2cam_r, batch.position, drot,
    )  # fmt: skip
    for k, c in enumerate(cams):
        ref_uv, ref = project_tsai_jacobian(
            points[k], c.f, c.cx, c.cy, c.sx, c.kappa1, c.world2cam_r, c.position, drot[k]
        )
        assert_array_equal(jac[k], ref)
        assert_array_equal(uv[k], ref_uv)
        assert_allclose(uv[k], c.project(points[k]), rtol=0, atol=1e-10)


def test_cameras_of_different_sizes_cannot_be_stacked() -> None:
    cam = paper_camera(1)
    with pytest.raises(ValueError, match="image size"):
        TsaiCameras.from_cameras([cam, cam.with_(image_size=(640, 480))])


def test_a_stack_checks_its_rotations() -> None:
    cam = paper_camera(1)
    batch = TsaiCameras.from_cameras([cam])
    with pytest.raises(ValueError, match="rotation"):
        TsaiCameras(batch.f, batch.cx, batch.cy, batch.kappa1, batch.sx,
                    2 * batch.world2cam_r, batch.position)  # fmt: skip
    assert_array_equal(batch.f, [cam.f])
