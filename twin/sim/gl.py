"""Choosing the headless OpenGL backend for MuJoCo's offscreen renderer.

MuJoCo picks its OpenGL platform from the ``MUJOCO_GL`` environment variable when it is
first imported, so the choice is made here, before that import (:mod:`twin.sim` calls
:func:`configure_headless` first thing):

- ``MUJOCO_GL`` already set (by the user, or ``glfw`` for a desktop): left alone, but
  ``egl`` or ``osmesa`` without its library raises :class:`RenderBackendError` at once
  (importing mujoco would otherwise fail deep inside PyOpenGL);
- otherwise EGL (Mesa's software rasteriser, or a GPU's driver) when ``libEGL`` is
  installed, else OSMesa when ``libOSMesa`` is;
- neither: nothing is set, the physics works, and the first renderer raises
  :class:`RenderBackendError` saying what to install.

A library can be present and still fail to give a context (no Mesa DRI drivers, say):
:func:`make_renderer` turns that failure into the same error, with the same advice.
"""

from __future__ import annotations

import ctypes.util
import os
import sys
from collections.abc import Callable, MutableMapping

# Backends in order of preference, with the shared library each needs.
BACKENDS: dict[str, str] = {"egl": "EGL", "osmesa": "OSMesa"}

INSTALL_HINT = (
    "headless rendering needs Mesa's EGL or OSMesa. On Debian or Ubuntu: "
    "`apt-get install libegl1 libgl1-mesa-dri` (EGL, the default), or "
    "`apt-get install libosmesa6` and `export MUJOCO_GL=osmesa` (the fallback). "
    "On a desktop, `export MUJOCO_GL=glfw` renders through the window system instead"
)


class RenderBackendError(RuntimeError):
    """No OpenGL context could be made for offscreen rendering."""


def choose_backend(
    find_library: Callable[[str], str | None] = ctypes.util.find_library,
) -> str | None:
    """The first backend of :data:`BACKENDS` whose library is installed, or None."""
    for backend, library in BACKENDS.items():
        if find_library(library):
            return backend
    return None


def configure_headless(
    environ: MutableMapping[str, str] | None = None,
    find_library: Callable[[str], str | None] = ctypes.util.find_library,
) -> str | None:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) to a working headless backend.

    Args:
        environ: the environment to update (default ``os.environ``).
        find_library: how to look a shared library up (for tests).

    Returns:
        The backend in effect: the one already set, the one chosen, or None when none
        was set and no backend library is installed (or mujoco was imported first, too
        late to choose).

    Raises:
        RenderBackendError: ``MUJOCO_GL`` names egl or osmesa and its library is missing.
    """
    env = os.environ if environ is None else environ
    current = env.get("MUJOCO_GL", "").strip().lower()
    if current:
        library = BACKENDS.get(current)
        if library is not None and not find_library(library):
            raise RenderBackendError(
                f"MUJOCO_GL={current} but lib{library} is not installed. Fix: {INSTALL_HINT}"
            )
        return current
    if environ is None and "mujoco" in sys.modules:
        return None
    backend = choose_backend(find_library)
    if backend is not None:
        env["MUJOCO_GL"] = backend
        env.setdefault("PYOPENGL_PLATFORM", backend)
    return backend


def backend_error(cause: BaseException | str) -> RenderBackendError:
    """The error raised when no rendering context can be made, with what to install."""
    backend = os.environ.get("MUJOCO_GL", "") or "none found"
    return RenderBackendError(
        f"cannot render offscreen (MUJOCO_GL={backend}): {cause}. Fix: {INSTALL_HINT}"
    )


def make_renderer(model: object, height: int, width: int) -> object:
    """A :class:`mujoco.Renderer`, or :class:`RenderBackendError` naming what to install.

    The offscreen buffer is made for this image (the model's ``offwidth`` and
    ``offheight`` are raised for the creation only, so that one large render does not make
    every later renderer allocate as much).
    """
    import mujoco

    vis = model.vis.global_  # type: ignore[attr-defined]
    saved = (int(vis.offwidth), int(vis.offheight))
    vis.offwidth = max(saved[0], int(width))
    vis.offheight = max(saved[1], int(height))
    try:
        # Every geom of a map's thousands of boxes is drawn: none left out of the scene.
        max_geom = max(10_000, 2 * int(model.ngeom))  # type: ignore[attr-defined]
        return mujoco.Renderer(model, height=int(height), width=int(width), max_geom=max_geom)
    except ValueError:
        raise
    except Exception as err:
        cause = f"{type(err).__name__}: {err}"
        if not os.environ.get("MUJOCO_GL"):
            cause += (
                " (MUJOCO_GL is not set: import twin.sim before mujoco, or set MUJOCO_GL=egl "
                "before Python starts)"
            )
        raise backend_error(cause) from err
    finally:
        vis.offwidth, vis.offheight = saved
