"""The device models: load alone, step quietly, named, and agree with their constants."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from twin.instruments.marker import MarkerAssembly
from twin.scenario.robots import INSTRUMENT_HEIGHT, MODELS_DIR, PIONEER3AT, PIONEER3DX

from .helpers import unnamed

DEVICES = ["pioneer3at", "pioneer3dx"]


@pytest.mark.parametrize("device", DEVICES)
def test_device_scene_loads_and_steps_without_warnings(device):
    model = mujoco.MjModel.from_xml_path(str(MODELS_DIR / device / "scene.xml"))
    data = mujoco.MjData(model)
    z0 = None
    for _ in range(round(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
        if z0 is None:
            z0 = data.qpos[2]
    assert [w.number for w in data.warning] == [0] * len(data.warning)
    assert not unnamed(model)
    # Resting on its wheels, level and still.
    assert abs(data.qpos[2]) < 2e-3
    assert np.linalg.norm(data.qvel[:6]) < 1e-3


@pytest.mark.parametrize("device", DEVICES)
def test_device_file_alone_compiles(device):
    model = mujoco.MjModel.from_xml_path(str(MODELS_DIR / device / f"{device}.xml"))
    assert model.nu >= 2
    assert (MODELS_DIR / device / "README.md").is_file()


@pytest.mark.parametrize("platform", [PIONEER3AT, PIONEER3DX])
def test_platform_constants_match_the_model(platform):
    model = mujoco.MjModel.from_xml_path(str(platform.xml_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    wheels = platform.wheels_left + platform.wheels_right
    for name in wheels:
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        assert model.geom_size[g, 0] == pytest.approx(platform.wheel_radius)
        b = model.geom_bodyid[g]
        assert data.xpos[b, 2] == pytest.approx(platform.wheel_radius)
    left = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, platform.wheels_left[0])
    right = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, platform.wheels_right[0])
    assert data.xpos[left, 1] - data.xpos[right, 1] == pytest.approx(platform.track)
    chassis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "chassis")
    half = model.geom_size[chassis]
    assert 2 * half[0] == pytest.approx(platform.length)
    assert 2 * half[1] == pytest.approx(platform.width)
    assert model.geom_pos[chassis, 2] + half[2] == pytest.approx(platform.height)
    assert model.geom_pos[chassis, 2] - half[2] == pytest.approx(platform.ground_clearance)


def test_instrument_site_height():
    model = mujoco.MjModel.from_xml_path(str(PIONEER3AT.xml_path))
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "instrument")
    np.testing.assert_allclose(model.site_pos[site], [0.0, 0.0, INSTRUMENT_HEIGHT])
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "inclinometer") >= 0


def test_marker_sites_sit_where_the_marker_assembly_says():
    model = mujoco.MjModel.from_xml_path(str(PIONEER3DX.xml_path))
    marker = MarkerAssembly()
    for k, p in enumerate(marker.cubes_body):
        s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"cube{k}")
        np.testing.assert_allclose(model.site_pos[s], p)
    assert len(marker.leds_body) == 4
    for k, p in enumerate(marker.leds_body):
        s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"led{k}")
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"led{k}")
        np.testing.assert_allclose(model.site_pos[s], p)
        np.testing.assert_allclose(model.geom_pos[g], p)
        # One material per LED, so each can be switched alone.
        assert (
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, model.geom_matid[g]) == f"led{k}"
        )
