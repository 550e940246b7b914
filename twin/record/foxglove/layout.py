"""A ready Foxglove layout for a run's log (``docs/foxglove-layout.json``), built with the
SDK's layout classes (:mod:`foxglove.layouts`).

- a 3D panel, fixed frame W, following the parent (``parent/estimate``), with every scene
  topic, both instrument tracks and the children's tracks (:data:`CHILDREN`);
- plots of the parent's position variances at each CPS fix (``/campaign/parent_fix``, m²)
  and of each calibration's reprojection sigma (``/campaign/calibration``, px);
- Foxglove's log panel on ``/foxglove/log``;
- an image panel of :data:`IMAGED` (the camera every scenario of the project has): its
  images (render fidelity, and a rig's cameras) with the LEDs found and the measured LED
  points projected through its calibration, as last calibrated.

``python -m twin.record.foxglove.layout`` prints it (the shipped file is its output).
"""

from __future__ import annotations

import json

import foxglove.layouts as fl

from twin.record.foxglove import frames
from twin.record.foxglove.images import camera_topics
from twin.record.foxglove.stream import (
    CALIBRATION,
    LOG,
    PARENT_FIX,
    SCENE_CAMERAS,
    SCENE_COVARIANCE,
    SCENE_POINTS,
    SCENE_ROBOTS,
    SCENE_SIGHTS,
    SCENE_SITE,
    TRACK_ESTIMATE,
    TRACK_TRUTH,
    track_topic,
)

FOLLOWED = frames.robot_frame("parent")
"""The frame the 3D panel follows."""
CHILDREN = ("child1", "child2")
"""The children whose tracks the 3D panel shows (the names every scenario gives them)."""
IMAGED = "cam1"
"""The camera of the image panel (Foxglove's panel settings choose another)."""


def layout() -> fl.Layout:
    """The layout: the 3D panel on the left, the plots and the log on the right."""
    scene = {
        topic: fl.BaseRendererSceneUpdateTopicSettings(visible=True)
        for topic in (
            SCENE_SITE,
            SCENE_CAMERAS,
            SCENE_POINTS,
            SCENE_COVARIANCE,
            SCENE_SIGHTS,
            SCENE_ROBOTS,
        )
    }
    tracks = {
        TRACK_ESTIMATE: fl.BaseRendererPosesTopicSettings(
            visible=True, type="line", line_width=0.02
        ),
        TRACK_TRUTH: fl.BaseRendererPosesTopicSettings(visible=True, type="line", line_width=0.01),
        **{
            track_topic(child, which): fl.BaseRendererPosesTopicSettings(
                visible=True, type="line", line_width=width
            )
            for child in CHILDREN
            for which, width in (("estimate", 0.02), ("truth", 0.01))
        },
    }
    three_d = fl.ThreeDeePanel(
        title="campaign (W, following the parent)",
        config=fl.ThreeDeeConfig(
            fixed_frame=frames.WORLD,
            follow_tf=FOLLOWED,
            follow_mode="follow-position",
            topics={**scene, **tracks},
            camera_state=fl.ThreeDeeCameraState(distance=25.0, phi=50.0, perspective=True),
        ),
    )
    variances = fl.PlotPanel(
        title="parent position variance at each fix (m²)",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=f"{PARENT_FIX}.covariance[{i}][{i}]", label=label)
                for i, label in ((1, "x"), (2, "y"), (3, "z"))
            ],
        ),
    )
    errors = fl.PlotPanel(
        title="calibration reprojection sigma (px)",
        config=fl.PlotConfig(paths=[fl.PlotSeries(value=f"{CALIBRATION}.sigma_px", label="sigma")]),
    )
    log = fl.LogPanel(title="campaign log", config=fl.LogConfig(topic_to_render=LOG))
    topics = camera_topics(IMAGED)
    image = fl.ImagePanel(
        title=f"{IMAGED}: LEDs found (green), measured points projected (magenta)",
        config=fl.ImageConfig(
            image_mode=fl.ImageModeConfig(
                image_topic=topics["image"],
                calibration_topic=topics["calibration"],
                annotations={topics["annotations"]: fl.ImageAnnotationSettings(visible=True)},
            ),
        ),
    )
    right = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(content=image),
            fl.SplitItem(content=variances),
            fl.SplitItem(content=errors),
            fl.SplitItem(content=log),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row",
            items=[fl.SplitItem(proportion=2, content=three_d), fl.SplitItem(content=right)],
        )
    )


def layout_json() -> str:
    """The layout as the shipped file's text (indented JSON, one trailing newline)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + "\n"


if __name__ == "__main__":
    print(layout_json(), end="")
