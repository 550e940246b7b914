"""Choosing the headless OpenGL backend, and the errors that say what to install."""

from __future__ import annotations

import pytest

from twin.sim import gl


def _libs(*present):
    return lambda name: f"lib{name}.so.1" if name in present else None


def test_egl_is_preferred_and_osmesa_is_the_fallback():
    assert gl.choose_backend(_libs("EGL", "OSMesa")) == "egl"
    assert gl.choose_backend(_libs("OSMesa")) == "osmesa"
    assert gl.choose_backend(_libs()) is None


def test_configure_sets_the_chosen_backend_for_mujoco_and_pyopengl():
    env: dict[str, str] = {}
    assert gl.configure_headless(env, _libs("OSMesa")) == "osmesa"
    assert env == {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}


def test_configure_leaves_a_users_choice_alone():
    env = {"MUJOCO_GL": "glfw"}
    assert gl.configure_headless(env, _libs()) == "glfw"
    assert env == {"MUJOCO_GL": "glfw"}


def test_configure_without_any_library_sets_nothing():
    env: dict[str, str] = {}
    assert gl.configure_headless(env, _libs()) is None
    assert env == {}


def test_a_backend_whose_library_is_missing_is_an_error_naming_the_package():
    with pytest.raises(gl.RenderBackendError, match="libOSMesa is not installed") as info:
        gl.configure_headless({"MUJOCO_GL": "osmesa"}, _libs("EGL"))
    assert "apt-get install libosmesa6" in str(info.value)
    assert "libegl1 libgl1-mesa-dri" in str(info.value)


def test_a_renderer_that_cannot_start_says_what_to_install(monkeypatch):
    import mujoco

    def no_context(*args, **kwargs):
        raise RuntimeError("eglInitialize failed")

    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    monkeypatch.setattr(mujoco, "Renderer", no_context)
    with pytest.raises(gl.RenderBackendError, match="eglInitialize failed") as info:
        gl.make_renderer(model, 16, 16)
    assert "apt-get install libegl1" in str(info.value)
    # Without MUJOCO_GL (mujoco imported before twin.sim) the error says so.
    monkeypatch.setenv("MUJOCO_GL", "")
    with pytest.raises(gl.RenderBackendError, match=r"import twin\.sim before mujoco"):
        gl.make_renderer(model, 16, 16)


def test_a_large_renderer_does_not_enlarge_the_later_ones():
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    before = (model.vis.global_.offwidth, model.vis.global_.offheight)
    with gl.make_renderer(model, 900, 1300) as r:
        assert r.render().shape == (900, 1300, 3)
    assert (model.vis.global_.offwidth, model.vis.global_.offheight) == before
