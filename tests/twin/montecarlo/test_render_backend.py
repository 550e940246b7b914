"""Monte Carlo at the render fidelity without ``MUJOCO_GL``: the command and its worker
processes choose the headless OpenGL backend as ``twin run`` does."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from twin.sim.gl import choose_backend

ROOT = Path(__file__).resolve().parents[3]

# What the command (twin.montecarlo.run) and a worker process (unpickling a trial's
# function from twin.montecarlo.trial) import, in a fresh interpreter, then a renderer.
WORKER = """
import os
import twin.montecarlo.run
import twin.montecarlo.trial
import mujoco
from twin.sim.gl import make_renderer
model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
renderer = make_renderer(model, 8, 8)
renderer.close()
print(os.environ["MUJOCO_GL"])
"""


@pytest.mark.skipif(choose_backend() is None, reason="no EGL or OSMesa library installed")
def test_monte_carlo_renders_without_mujoco_gl():
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    done = subprocess.run(
        [sys.executable, "-c", WORKER], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == choose_backend()
