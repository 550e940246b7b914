"""Shared fixtures: cameras and LED data sets like the paper's."""

from __future__ import annotations

import numpy as np
import pytest

from calib.synthetic import led_points, paper_camera


@pytest.fixture(params=[1, 2, 3], ids=["cam1", "cam2", "cam3"])
def paper_cam(request: pytest.FixtureRequest):
    return paper_camera(request.param)


@pytest.fixture
def cam1():
    return paper_camera(1)


@pytest.fixture
def cam1_points(cam1):
    """70 LED points like the paper's data set, in view of camera 1 (fixed seed)."""
    return led_points(cam1, 70, np.random.default_rng(7))
