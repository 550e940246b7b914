"""Shared helpers for the localization tests."""

import numpy as np

from calib.rotation import rot_z


def measure_from(yaw, translation, points_world):
    """Noise-free levelled-frame coordinates of world points seen from a parent pose."""
    return (np.asarray(points_world) - translation) @ rot_z(yaw)


def iso_cov(n, sigma):
    """(n, 3, 3) isotropic covariances of standard deviation ``sigma`` m."""
    return np.tile(np.eye(3) * sigma**2, (n, 1, 1))
