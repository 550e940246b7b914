"""Headless rendering for every test here: importing twin.sim chooses the OpenGL backend
(EGL, else OSMesa) before anything imports mujoco."""

import twin.sim  # noqa: F401
from tests.twin.report.figure_checks import saved  # noqa: F401  (a fixture)
