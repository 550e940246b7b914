"""``twin render``: one image from a scenario's camera, robots at their start poses."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from twin.cli.scene import load_or_report
from twin.outputs import OutputError, check_file_target


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``render`` subcommand."""
    p = sub.add_parser(
        "render",
        help="render one image from a camera of a scenario",
        description=(
            "Render one image from a fixed camera of a scenario, with the robots at their "
            "start poses (after settling for 0.2 s), as a PNG: through the camera's lens "
            "(distortion) and sensor (noise, 8 bits) as it would see it, or with --pinhole "
            "as MuJoCo draws it. Rendering is headless (EGL, else OSMesa; MUJOCO_GL "
            "overrides)."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument("--camera", required=True, help="camera name, e.g. cam1 (required)")
    p.add_argument(
        "--leds", choices=["on", "off"], default="off", help="the children's LEDs (default off)"
    )
    p.add_argument(
        "--pinhole",
        action="store_true",
        help="MuJoCo's pinhole image, without the lens and sensor models (default: through them)",
    )
    p.add_argument(
        "--out", type=Path, required=True, metavar="FILE.png", help="output image (required)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Render and save; exit code 0, or 2 for an invalid scenario or unknown camera."""
    console = Console(highlight=False, soft_wrap=True)
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    check_file_target(args.out, "--out")
    if args.out.suffix.lower() != ".png":
        raise OutputError(f"--out {args.out}: the image is written as PNG; give a .png file")
    names = [c.name for c in sc.cameras]
    if args.camera not in names:
        Console(stderr=True, highlight=False).print(
            f"{args.scenario}: --camera {args.camera!r}: no such camera; expected one of "
            f"{', '.join(names)}",
            markup=False,
            soft_wrap=True,
        )
        return 2
    import twin.sim  # noqa: F401  (chooses the headless OpenGL backend)
    from twin.png import save_png
    from twin.sim.capture import CameraSimulator
    from twin.sim.render import CameraRenderer
    from twin.sim.world import build_world

    world = build_world(sc)
    world.run(0.2)
    for child in sc.robots.children:
        world.sensing.set_leds(child.name, args.leds == "on")
    if args.pinhole:
        with CameraRenderer(world) as renderer:
            image = renderer.render(args.camera)
    else:
        with CameraSimulator(world) as sim:
            image = sim.capture(args.camera).image
    path = save_png(image, args.out)
    h, w = image.shape[:2]
    kind = "pinhole" if args.pinhole else "lens and sensor"
    console.print(f"wrote {path} ({w} x {h} px, camera {args.camera}, {kind}, LEDs {args.leds})")
    return 0
