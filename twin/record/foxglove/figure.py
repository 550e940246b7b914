"""The scene that a log's ``foxglove.SceneUpdate`` messages describe, drawn headless with
matplotlib (not by the Foxglove app): a top view and a 3D view of the site, the route and
stations, the cameras' frustums (as built and as calibrated), the LED points coloured by
their residual, the parent's covariance ellipsoids and the failed lines of sight.

Each entity in W is drawn as the log's last message on its topic left it (as Foxglove shows
it at the end of the log); those locked to a robot's frame (its marker assembly) and the
lines of sight that expire (the shots that succeeded) are left out. Reading the protobuf
messages needs ``mcap-protobuf-support`` (the dev extra).

``python -m twin.record.foxglove.figure LOG.mcap OUT.png`` draws one.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin.record.foxglove.stream import TOPICS

BACKGROUND = "#1f1f26"
"""Foxglove's 3D panel's dark background."""
Z_EXAGGERATION = 2.0
"""The 3D view's heights are drawn this many times taller (a hall is flat)."""
SCENE_TOPICS = tuple(t for t, schema in TOPICS.items() if schema == "foxglove.SceneUpdate")


@dataclass
class Scene:
    """What the SceneUpdate messages leave, as plain arrays in W (m) and RGBA colours.

    Attributes:
        boxes: (centre (3,), size (3,), yaw rad, colour) of every cube.
        segments: (points (N, 3), colour, strip) of every line (strip: a polyline; else
            pairs of points).
        spheres: (centre (3,), size (3,), colour) of every sphere.
        texts: (position (3,), text, colour).
        entities: how many entities were drawn, by topic.
    """

    boxes: list[tuple[np.ndarray, np.ndarray, float, tuple]] = field(default_factory=list)
    segments: list[tuple[np.ndarray, tuple, bool]] = field(default_factory=list)
    spheres: list[tuple[np.ndarray, np.ndarray, tuple]] = field(default_factory=list)
    texts: list[tuple[np.ndarray, str, tuple]] = field(default_factory=list)
    entities: dict[str, int] = field(default_factory=dict)


def scene_updates(path: str | Path) -> Iterator[tuple[str, Any]]:
    """The ``foxglove.SceneUpdate`` messages of a log, decoded, in order: (topic, message)."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    factory = DecoderFactory()
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=list(SCENE_TOPICS)):
            if schema is not None and schema.name == "foxglove.SceneUpdate":
                yield channel.topic, factory.decoder_for("protobuf", schema)(message.data)


def read_scene(path: str | Path) -> Scene:
    """The scene at the end of the log ``path``: each entity as its last message left it."""
    latest: dict[tuple[str, str], Any] = {}
    for topic, update in scene_updates(path):
        for d in update.deletions:
            if d.type == 1:  # ALL
                latest = {k: v for k, v in latest.items() if k[0] != topic}
            else:
                latest.pop((topic, d.id), None)
        for e in update.entities:
            if e.frame_id != "W":  # locked to a robot: it moves (the markers)
                continue
            expires = e.HasField("lifetime") and (e.lifetime.seconds or e.lifetime.nanos)
            if expires:  # a line of sight of a shot that succeeded: gone by the end
                latest.pop((topic, e.id), None)
                continue
            latest[(topic, e.id)] = e
    scene = Scene()
    for (topic, _), e in latest.items():
        scene.entities[topic] = scene.entities.get(topic, 0) + 1
        for c in e.cubes:
            yaw = 2.0 * math.atan2(c.pose.orientation.z, c.pose.orientation.w)
            scene.boxes.append((_xyz(c.pose.position), _xyz(c.size), yaw, _rgba(c.color)))
        for line in e.lines:
            pts = np.array([_xyz(p) for p in line.points]).reshape(-1, 3) + _xyz(line.pose.position)
            scene.segments.append((pts, _rgba(line.color), line.type == 0))
        for s in e.spheres:
            scene.spheres.append((_xyz(s.pose.position), _xyz(s.size), _rgba(s.color)))
        for t in e.texts:
            scene.texts.append((_xyz(t.pose.position), t.text, _rgba(t.color)))
    return scene


def draw_scene(scene: Scene, out: str | Path, title: str) -> Path:
    """Draw ``scene`` (top view and 3D view) into the PNG ``out``; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse, Polygon

    fig = plt.figure(figsize=(11, 8.5), facecolor=BACKGROUND)
    grid = fig.add_gridspec(2, 1, height_ratios=(1, 1.1))
    top = fig.add_subplot(grid[0], facecolor=BACKGROUND)
    view = fig.add_subplot(grid[1], projection="3d", facecolor=BACKGROUND)
    for center, size, yaw, c in scene.boxes:
        corners = _box_corners(center, size, yaw)
        top.add_patch(Polygon(corners[:, :2], closed=True, facecolor=c, edgecolor="none"))
    for pts, c, strip in scene.segments:
        for a in _pieces(pts, strip):
            top.plot(a[:, 0], a[:, 1], color=c, lw=1.5 if strip else 0.8)
            view.plot(a[:, 0], a[:, 1], a[:, 2], color=c, lw=1.5 if strip else 0.8)
    small = [(p, s, c) for p, s, c in scene.spheres if max(s) < 0.1]
    big = [(p, s, c) for p, s, c in scene.spheres if max(s) >= 0.1]
    if small:
        xyz = np.array([p for p, _, _ in small])
        colours = [c for _, _, c in small]
        top.scatter(xyz[:, 0], xyz[:, 1], s=4, c=colours, zorder=3)
        view.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=3, c=colours)
    for p, s, c in big:  # stations and covariance ellipsoids (axis-aligned in the top view)
        top.add_patch(Ellipse((p[0], p[1]), s[0], s[1], facecolor=c, edgecolor="none", zorder=2))
    for p, text, c in scene.texts:
        top.annotate(
            text, (p[0], p[1]), color=c, fontsize=7, xytext=(3, 3), textcoords="offset points"
        )
    top.set_aspect("equal")
    top.autoscale_view()
    top.set_title("top view", color="white")
    view.set_title(f"3D view (heights x{Z_EXAGGERATION:g})", color="white")
    for ax in (top, view):
        ax.tick_params(colors="0.7", labelsize=7)
        ax.set_xlabel("x (m, W)", color="0.7")
        ax.set_ylabel("y (m, W)", color="0.7")
    view.set_zlabel("z (m)", color="0.7")
    lo, hi = np.array(view.get_w_lims()).reshape(3, 2).T
    view.set_box_aspect(np.maximum(hi - lo, 1e-3) * (1.0, 1.0, Z_EXAGGERATION), zoom=1.25)
    for axis in (view.xaxis, view.yaxis, view.zaxis):
        axis.set_pane_color((0.15, 0.15, 0.18, 1.0))
    fig.suptitle(title, color="white", fontsize=11)
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=110, facecolor=BACKGROUND)
    plt.close(fig)
    return out


def _xyz(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def _rgba(c: Any) -> tuple[float, float, float, float]:
    return (c.r, c.g, c.b, c.a)


def _box_corners(center: np.ndarray, size: np.ndarray, yaw: float) -> np.ndarray:
    """The 4 corners (4, 2) of a box turned ``yaw`` about z, seen from above."""
    hx, hy = size[0] / 2, size[1] / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = math.cos(yaw), math.sin(yaw)
    return local @ np.array([[c, s], [-s, c]]) + center[:2]


def _pieces(points: np.ndarray, strip: bool) -> list[np.ndarray]:
    """A line's points as the polylines to draw: the strip whole, a list in pairs."""
    if strip:
        return [points]
    return [points[i : i + 2] for i in range(0, len(points) - 1, 2)]


def main(argv: list[str] | None = None) -> int:
    """Draw a log's scene; exit code 0, 2 for a log that cannot be read."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("log", type=Path, help="a run's log.mcap")
    p.add_argument("out", type=Path, help="the PNG to write")
    args = p.parse_args(argv)
    try:
        scene = read_scene(args.log)
    except (OSError, ValueError) as exc:
        print(f"error: {args.log}: {exc}", file=sys.stderr)
        return 2
    if not scene.entities:
        print(f"error: {args.log}: the log has no foxglove.SceneUpdate messages", file=sys.stderr)
        return 2
    title = (
        f"{args.log.parent.name}: the scene of the log's foxglove.SceneUpdate messages, "
        "drawn headless with matplotlib (not the Foxglove app)"
    )
    draw_scene(scene, args.out, title)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
