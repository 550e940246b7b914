"""Headless rendering for every test here: MUJOCO_GL must be set before mujoco is imported."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
