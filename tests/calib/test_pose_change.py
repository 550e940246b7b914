"""A camera moved by a shift and a turn, and the move measured back: one convention."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.pose_change import moved_camera, pose_change
from calib.synthetic import paper_camera


def test_the_move_is_measured_back():
    camera = paper_camera(1)
    rng = np.random.default_rng(0)
    for _ in range(20):
        shift = rng.normal(0, 0.1, 3)
        turn = rng.normal(0, 0.05, 3)
        moved = moved_camera(camera, shift, turn)
        got_shift, got_turn = pose_change(camera, moved)
        assert_allclose(got_shift, shift, atol=1e-12)
        assert_allclose(got_turn, turn, atol=1e-12)
        assert moved.f == camera.f
        assert moved.kappa1 == camera.kappa1


def test_a_shift_moves_the_optical_centre_and_keeps_the_axes():
    camera = paper_camera(2)
    moved = moved_camera(camera, [0.02, -0.01, 0.005], [0, 0, 0])
    assert_allclose(moved.position - camera.position, [0.02, -0.01, 0.005], atol=1e-12)
    assert_allclose(moved.world2cam_r, camera.world2cam_r, atol=1e-15)


def test_a_turn_is_about_the_cameras_own_axes():
    camera = paper_camera(1)
    # About its own z axis (roll): the optical axis stays; about y (pan): it turns sideways.
    roll = moved_camera(camera, np.zeros(3), [0, 0, 0.1])
    assert_allclose(roll.optical_axis, camera.optical_axis, atol=1e-12)
    assert_allclose(roll.position, camera.position, atol=1e-12)
    pan = moved_camera(camera, np.zeros(3), [0, np.radians(1.0), 0])
    angle = np.arccos(np.clip(pan.optical_axis @ camera.optical_axis, -1, 1))
    assert angle == pytest.approx(np.radians(1.0), rel=1e-9)
    # The image's x axis (right) does not turn under a pan.
    assert_allclose(pan.world2cam_r[1], camera.world2cam_r[1], atol=1e-12)


@pytest.mark.parametrize("bad", [[0, 0], [0, 0, np.nan], "x"])
def test_bad_vectors_are_refused_by_name(bad):
    with pytest.raises(ValueError, match="shift_m must be 3 finite numbers"):
        moved_camera(paper_camera(1), bad, [0, 0, 0])
