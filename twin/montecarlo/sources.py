"""The noise sources of an error budget, and scenarios with one source alone.

A budget runs the campaign with every source (``all``) and with each source alone; the
instruments still advertise their full noise (the estimators weigh the data as in the
real run), only the simulated errors come from the one source.
"""

from __future__ import annotations

from twin.scenario import Scenario

ALL = "all"
"""The configuration with every noise source of the scenario."""

SOURCES: dict[str, str] = {
    "distance": "total-station distance noise and its output rounding",
    "angle": "total-station angle noise and its output rounding",
    "pointing": "where on the prism the total station measures "
    "(noise.total_station.pointing_sigma)",
    "inclination": "inclinometer noise",
    "led_detection": "LED detection in the image (geometric: noise.led_detection_px; "
    "render: the camera's sensor noise)",
    "led_centroid": "the real camera's LED centroid error (noise.led_centroid_px and each "
    "camera's led_centroid_px)",
    "stopping": "robot stopping error and wheel odometry",
    "creep": "standing children moving while the parent drives (noise.child_creep_m)",
    "marker": "error of the marker assembly's geometry (noise.marker_geometry_m)",
}
"""Each source by name, with what it switches on."""

_TOTAL_STATION = {
    "distance": ("distance_sigma_const", "distance_sigma_ppm", "distance_resolution"),
    "angle": ("angle_sigma", "angle_resolution"),
    "pointing": ("pointing_sigma",),
}
_NOISE_KEY = {
    "led_centroid": "led_centroid_px",
    "creep": "child_creep_m",
    "marker": "marker_geometry_m",
}


def configurations(budget: bool) -> tuple[str, ...]:
    """The configurations of a run: ``all``, then each source alone when ``budget``."""
    return (ALL, *SOURCES) if budget else (ALL,)


def isolate(scenario: Scenario, source: str) -> Scenario:
    """``scenario`` with only ``source`` noisy (``all``: the scenario itself).

    Raises:
        ValueError: for an unknown source, naming the known ones.
    """
    if source == ALL:
        return scenario
    if source not in SOURCES:
        raise ValueError(f"unknown noise source {source!r}; known: {', '.join(SOURCES)}")
    quiet = scenario.without_noise()
    full, off = scenario.noise, quiet.noise
    noise = off
    cameras = quiet.cameras
    if source in _TOTAL_STATION:
        keys = _TOTAL_STATION[source]
        ts = off.total_station.model_copy(update={k: getattr(full.total_station, k) for k in keys})
        noise = off.model_copy(update={"total_station": ts})
    elif source == "inclination":
        noise = off.model_copy(update={"inclinometer": full.inclinometer})
    elif source == "led_detection":
        noise = off.model_copy(update={"led_detection_px": full.led_detection_px})
        # The cameras' sensors, without their own centroid errors (led_centroid's).
        cameras = tuple(
            c.model_copy(update={"led_centroid_px": q.led_centroid_px})
            for c, q in zip(scenario.cameras, quiet.cameras, strict=True)
        )
    elif source == "stopping":
        noise = off.model_copy(update={"stopping": full.stopping, "odometry": full.odometry})
    elif source in _NOISE_KEY:
        key = _NOISE_KEY[source]
        noise = off.model_copy(update={key: getattr(full, key)})
        if source == "led_centroid":
            # Each camera's own centroid error belongs to this source too.
            cameras = tuple(
                q.model_copy(update={"led_centroid_px": c.led_centroid_px})
                for c, q in zip(scenario.cameras, quiet.cameras, strict=True)
            )
    return quiet.model_copy(update={"noise": noise, "cameras": cameras})


UNPREDICTED: dict[str, str] = {
    "creep": "the campaign's CPS allows a standing child less creep (campaign.child_creep_m) "
    "than the twin simulates",
    "marker": "an assembly's surveying error is shared by every point of its child",
}
"""Sources the campaign's covariance propagation does not model, and why."""


def unpredicted(scenario: Scenario) -> list[str]:
    """The sources of :data:`UNPREDICTED` that ``scenario`` switches on."""
    on = {
        "creep": scenario.noise.child_creep_m > scenario.campaign.child_creep_m,
        "marker": scenario.noise.marker_geometry_m > 0,
    }
    return [name for name in UNPREDICTED if on[name]]
