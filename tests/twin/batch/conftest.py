"""Headless rendering for every test here: importing twin.sim chooses the OpenGL backend
(EGL, else OSMesa) before anything imports mujoco."""

import twin.sim  # noqa: F401
