"""What can be seen in a world: lines of sight by ray casts, the children's LEDs, the
lights' level.

:class:`Sensing` acts on a world's MuJoCo model and data: the total station asks it
whether a prism is in sight, the cameras render what its LEDs and lights show.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.sim.robots import N_LEDS, RobotHandle

LED_ON_RGBA = (1.0, 0.35, 0.25, 1.0)
"""An LED's colour when lit (the "off" state is the material in the MJCF file): bright
enough, with :data:`LED_ON_EMISSION`, to saturate every channel, so a lit LED is a uniform
disc without shading."""
LED_ON_EMISSION = 5.0

MAX_RAY_RECASTS = 64
"""Most casts of one ray that may step past geoms of the robot it ignores."""

SIGHT_GROUPS = np.array([1, 0, 1, 0, 0, 0], dtype=np.uint8)
"""Geom groups that block lines of sight: the space (0) and the robots' visual geoms (2)."""


class Sensing:
    """Lines of sight, LEDs and lights of a world.

    Args:
        model, data: the world's MuJoCo objects.
        robots: handle of each robot by name.
        children: the children's names (whose LEDs it switches).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        robots: Mapping[str, RobotHandle],
        children: Sequence[str],
    ) -> None:
        self.model, self.data = model, data
        self.robots = robots
        self._led_material = {
            child: [
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MATERIAL, f"{child}/led{k}")
                for k in range(N_LEDS)
            ]
            for child in children
        }
        for child, ids in self._led_material.items():
            if min(ids) < 0:
                raise KeyError(f"the model has no LED materials for {child!r}")
        self._led_off = {
            mid: (model.mat_rgba[mid].copy(), float(model.mat_emission[mid]))
            for ids in self._led_material.values()
            for mid in ids
        }
        # The lights at level 1: each light's diffuse and specular, the headlight's.
        self._light_base = (
            model.light_diffuse.copy(),
            model.light_specular.copy(),
            np.array(model.vis.headlight.ambient, dtype=float),
            np.array(model.vis.headlight.diffuse, dtype=float),
        )
        self._light_level = 1.0

    def reset(self) -> None:
        """Every LED off, the lights at the scenario's level."""
        for mid, (rgba, emission) in self._led_off.items():
            self.model.mat_rgba[mid] = rgba
            self.model.mat_emission[mid] = emission
        self.set_light_level(1.0)

    # -- LEDs ------------------------------------------------------------------------------
    def _materials(self, child: str) -> list[int]:
        try:
            return self._led_material[child]
        except KeyError:
            raise KeyError(
                f"no LEDs on {child!r}; children: {sorted(self._led_material)}"
            ) from None

    def set_leds(self, child: str, on: bool | Sequence[bool]) -> None:
        """Switch a child's LEDs: one flag for all four, or a flag per LED (index 0 lowest
        in the default geometry). Changes the LED materials' colour and emission."""
        flags = [bool(on)] * N_LEDS if isinstance(on, bool | np.bool_) else [bool(f) for f in on]
        if len(flags) != N_LEDS:
            raise ValueError(f"give one flag or {N_LEDS} flags for the LEDs, got {len(flags)}")
        for mid, flag in zip(self._materials(child), flags, strict=True):
            rgba, emission = self._led_off[mid]
            self.model.mat_rgba[mid] = LED_ON_RGBA if flag else rgba
            self.model.mat_emission[mid] = LED_ON_EMISSION if flag else emission

    def leds_on(self, child: str) -> list[bool]:
        """Which of a child's LEDs are lit."""
        return [
            bool(self.model.mat_emission[mid] > 0.5 * LED_ON_EMISSION)
            for mid in self._materials(child)
        ]

    # -- lights ----------------------------------------------------------------------------
    @property
    def light_level(self) -> float:
        """Level of all lights relative to the scenario's, 1 at the start."""
        return self._light_level

    def set_light_level(self, level: float) -> None:
        """Scale every light (the overhead lights and the headlight's ambient and diffuse
        parts) to ``level`` times the scenario's: a flickering or dimming light."""
        if not (np.isfinite(level) and level >= 0.0):
            raise ValueError(f"the light level must be finite and >= 0, got {level}")
        diffuse, specular, ambient, head = self._light_base
        self.model.light_diffuse[:] = level * diffuse
        self.model.light_specular[:] = level * specular
        self.model.vis.headlight.ambient[:] = level * ambient
        self.model.vis.headlight.diffuse[:] = level * head
        self._light_level = float(level)

    # -- lines of sight --------------------------------------------------------------------
    def ray(
        self, origin: ArrayLike, direction: ArrayLike, exclude_robot: str | None = None
    ) -> tuple[float, str | None]:
        """Cast a ray against the space and the robots' visible geoms.

        Args:
            origin: (3,) start, m. direction: (3,) direction (any length).
            exclude_robot: a robot whose geoms are all ignored (e.g. the one looking).

        Returns:
            (distance along the unit direction in m, name of the geom hit), or
            (inf, None) if nothing is hit.
        """
        o = np.asarray(origin, dtype=float).reshape(3)
        d = np.asarray(direction, dtype=float).reshape(3)
        dist, g = self._cast(o, d / np.linalg.norm(d), exclude_robot)
        if g < 0:
            return dist, None
        return dist, mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g)

    def _cast(self, origin: NDArray, unit: NDArray, exclude_robot: str | None) -> tuple[float, int]:
        """:meth:`ray` from (3,) ``origin`` along a (3,) unit direction: (distance m, geom
        id), or (inf, -1) if nothing is hit."""
        skip = self.robots[exclude_robot].geoms if exclude_robot else frozenset()
        body = self.robots[exclude_robot].body if exclude_robot else -1
        gid = np.array([-1], dtype=np.int32)
        start, travelled = origin, 0.0
        # mj_ray ignores one body only: step past any hit on the excluded robot's other
        # bodies (its wheels, say) and cast again from there.
        for _ in range(MAX_RAY_RECASTS):
            dist = mujoco.mj_ray(self.model, self.data, start, unit, SIGHT_GROUPS, 1, body, gid)
            if dist < 0:
                return float("inf"), -1
            g = int(gid[0])
            if g not in skip:
                return travelled + float(dist), g
            step = float(dist) + 1e-6
            travelled += step
            start = start + step * unit
            body = int(self.model.geom_bodyid[g])
        raise RuntimeError(f"ray from {origin} kept hitting robot {exclude_robot!r}")

    def line_of_sight(
        self,
        p_from: ArrayLike,
        p_to: ArrayLike,
        exclude_robot: str | None = None,
        tolerance: float = 0.05,
    ) -> bool:
        """Whether nothing blocks the segment from ``p_from`` to ``p_to`` (m) except within
        ``tolerance`` (m) of ``p_to`` (the target's own housing, e.g. a prism or an LED)."""
        a = np.asarray(p_from, dtype=float).reshape(3)
        v = np.asarray(p_to, dtype=float).reshape(3) - a
        length = math.sqrt(v @ v)  # np.linalg.norm(v), without its overhead
        dist, _ = self._cast(a, v / length, exclude_robot)
        return bool(dist >= length - tolerance)
