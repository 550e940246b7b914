"""``twin detect``: find the LEDs of a switching sequence in camera images.

Two sources of images, one detector (:func:`calib.detection.detect_leds`):

- image files from any camera (``twin detect f0.png f1.png ... --sequence binary``), one
  per frame of the sequence, in order;
- the twin (``twin detect --scenario S --camera CAM``): the child is stood in the camera's
  view, the sequence is captured through the lens and sensor models, and the detections
  are compared with the ground truth.

It prints one row per LED (position and quality, or why it was not found) and, with
``--out DIR``, writes ``detections.json`` and ``overlay.png`` (the detections drawn on the
first lit frame; the truth too for the twin), plus the frames for the twin.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from calib.detection import DetectorConfig, LedDetections, SwitchingSequence, detect_leds
from calib.detection.sequence import MAX_LEDS
from twin.cli import arguments
from twin.cli.scene import load_or_report
from twin.outputs import check_folder, claim_folder, write_text_atomic
from twin.png import save_png

# Exit code when the detector ran but found no LED (1 is Python's own for a crash).
NO_LED_FOUND = 3

OUTPUTS = ("detections.json", "overlay.png", "frame_*.png")
"""What ``twin detect --out`` writes (and clears there with ``--overwrite``)."""

SEQUENCES = {"one-at-a-time": SwitchingSequence.one_at_a_time, "binary": SwitchingSequence.binary}


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``detect`` subcommand."""
    p = sub.add_parser(
        "detect",
        help="find the LEDs of a switching sequence in camera images (files or the twin)",
        description=(
            "Find each LED of a marker assembly in a sequence of frames taken while its "
            "LEDs are switched by a known pattern: the difference of lit and dark frames, "
            "a noise-derived threshold, sub-pixel centroids, identification by the "
            "switching code. Give the frames as image files, in order, or --scenario and "
            "--camera to capture them in the twin (with ground truth)."
        ),
    )
    p.add_argument("images", nargs="*", type=Path, help="one image file per frame, in order")
    p.add_argument(
        "--sequence",
        choices=sorted(SEQUENCES),
        default="binary",
        help="how the LEDs were switched: one at a time, or a constant-weight binary code "
        "(both with a dark frame first and last); default binary",
    )
    p.add_argument(
        "--leds",
        type=arguments.int_from_1_to(MAX_LEDS, "the most a switching sequence codes"),
        default=4,
        help=f"number of LEDs, 1 to {MAX_LEDS} (default 4)",
    )
    p.add_argument(
        "--led-line",
        type=arguments.finite_float,
        nargs="+",
        metavar="M",
        help="positions of the LEDs along their mast, m (tells a hidden LED from one out of "
        "view); default for --scenario: the marker's LED heights",
    )
    p.add_argument(
        "--channel",
        choices=["gray", "red", "green", "blue", "max"],
        default="gray",
        help="how colour images become one channel (default gray)",
    )
    p.add_argument(
        "--saturation",
        type=arguments.positive_float,
        metavar="DN",
        help="the camera's full scale (default: 255 for 8-bit images, else the smallest "
        "2^k - 1 that holds the brightest pixel; the twin's sensor bits)",
    )
    p.add_argument(
        "--scenario", type=Path, help="capture the frames in this scenario's twin (default: none)"
    )
    p.add_argument("--camera", help="the scenario's camera (required with --scenario)")
    p.add_argument("--child", default=None, help="the child whose LEDs are used (default: first)")
    p.add_argument(
        "--at",
        type=arguments.finite_float,
        nargs="+",
        metavar="V",
        help="X Y [YAW_DEG]: where the child stands, m (default: facing the camera, its "
        "second LED --distance away on the image's middle column)",
    )
    p.add_argument(
        "--distance", type=arguments.positive_float, default=5.0, help="see --at (m, default 5)"
    )
    p.add_argument(
        "--seed",
        type=arguments.seed,
        help="sensor-noise seed, 0 to 2^63 - 1 (default: the scenario's)",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="DIR",
        help="write detections and overlay here, an empty or new folder (default: print only)",
    )
    arguments.add_overwrite(p)
    p.set_defaults(func=run)


def _error(message: str) -> int:
    Console(stderr=True, highlight=False).print(message, markup=False, soft_wrap=True)
    return 2


def run(args: argparse.Namespace) -> int:
    """Detect and report; exit code 0, 2 for bad input, 3 when no LED was found."""
    console = Console(highlight=False, soft_wrap=True)
    if args.out is not None:  # a bad folder is refused before any work
        check_folder(args.out, "detect", OUTPUTS, overwrite=args.overwrite)
    sequence = SEQUENCES[args.sequence](args.leds)
    saturation = args.saturation
    truth = None
    if args.scenario is not None:
        if args.images:
            return _error("give image files or --scenario, not both")
        captured = _capture(args, sequence, console)
        if isinstance(captured, int):
            return captured
        frames, truth, led_line, source, full_scale = captured
        saturation = full_scale if saturation is None else saturation
    else:
        if args.camera is not None or args.at is not None:
            return _error("--camera and --at need --scenario")
        if not args.images:
            return _error("give the frames as image files, or --scenario to capture them")
        missing = [str(path) for path in args.images if not path.is_file()]
        if missing:
            return _error(f"no such image file: {', '.join(missing)}")
        if len(args.images) != sequence.n_frames:
            return _error(
                f"the {args.sequence} sequence of {args.leds} LEDs has {sequence.n_frames} "
                f"frames; got {len(args.images)} image file(s)"
            )
        loaded = _read_images(args.images)
        if isinstance(loaded, str):
            return _error(loaded)
        frames, led_line = loaded, args.led_line
        source = f"{len(frames)} image files"
    config = DetectorConfig(channel=args.channel, saturation_dn=saturation)
    try:
        result = detect_leds(frames, sequence, config=config, led_line=led_line)
    except ValueError as exc:
        return _error(f"cannot detect: {exc}")
    folder = None
    if args.out is not None:
        record = arguments.recorded(args)
        folder = claim_folder(args.out, "detect", OUTPUTS, record, overwrite=args.overwrite)
    console.print(f"{source}; {args.sequence} sequence, {sequence.n_frames} frames")
    _print_table(console, result, truth)
    for message in result.messages:
        console.print(f"note: {message}", markup=False)
    if folder is not None:
        _write(folder.path, frames, sequence, result, truth, console, truth is not None)
        folder.finished()
    return 0 if result.found.any() else NO_LED_FOUND


def _read_images(paths: list[Path]) -> list[NDArray] | str:
    """The images as RGB (or grey) arrays, or a message naming the file that failed."""
    import cv2

    out = []
    for path in paths:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            return f"{path}: cannot read this image file"
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGB if img.shape[2] == 4 else cv2.COLOR_BGR2RGB)
        out.append(img)
    shapes = {im.shape for im in out}
    if len(shapes) > 1:
        return f"the images differ in size or channels: {sorted(shapes)}"
    return out


def _capture(args: argparse.Namespace, sequence: SwitchingSequence, console: Console):
    """Frames captured in the twin, their truth pixels, the LED line and a description."""
    sc = load_or_report(args.scenario, console)
    if sc is None:
        return 2
    names = [c.name for c in sc.cameras]
    if args.camera is None:
        return _error(f"--scenario needs --camera: one of {', '.join(names)}")
    if args.camera not in names:
        return _error(f"--camera {args.camera!r}: expected one of {', '.join(names)}")
    children = [c.name for c in sc.robots.children]
    child = args.child or children[0]
    if child not in children:
        return _error(f"--child {child!r}: expected one of {', '.join(children)}")
    if args.leds != 4:
        return _error("the twin's marker has 4 LEDs: leave --leds at 4")
    import twin.sim  # noqa: F401  (chooses the headless OpenGL backend)
    from twin.sim.capture import CameraSimulator
    from twin.sim.placement import stand_for_led
    from twin.sim.world import build_world

    world = build_world(sc)
    marker = sc.marker.assembly()
    cam = world.camera(args.camera)
    if args.at is not None:
        if len(args.at) not in (2, 3):
            return _error(f"--at takes X Y [YAW_DEG], got {len(args.at)} number(s)")
        xy = np.array(args.at[:2])
        if len(args.at) == 3:
            yaw = float(np.radians(args.at[2]))
        else:
            yaw = float(np.arctan2(cam.position[1] - xy[1], cam.position[0] - xy[0]))
    else:
        placed = stand_for_led(
            cam, marker.leds_body[1], sc.space.floor_z, args.distance, 0.5 * cam.image_size[0]
        )
        if placed is None:
            return _error(
                f"camera {args.camera} does not see a point {args.distance:g} m away at the "
                "LED's height on its middle column; give --distance or --at"
            )
        xy, yaw = placed
    world.place(child, xy, yaw)
    with CameraSimulator(world, seed=args.seed) as sim:
        captured = sim.capture_sequence(args.camera, child, sequence)
    truth = captured[0].pixels(child)
    led_line = args.led_line if args.led_line is not None else marker.leds_body[:, 2]
    source = (
        f"{sc.name}: camera {args.camera}, {child} at ({xy[0]:.2f}, {xy[1]:.2f}) m, "
        f"yaw {np.degrees(yaw):.1f} deg"
    )
    full_scale = float(2 ** sc.camera(args.camera).sensor.bits - 1)
    return [f.image for f in captured], truth, led_line, source, full_scale


def _print_table(console: Console, result: LedDetections, truth: NDArray | None) -> None:
    table = Table(show_edge=False, pad_edge=False)
    for col in ("LED", "u px", "v px", "sigma px", "peak DN", "SNR", "result"):
        table.add_column(col, justify="right" if col != "result" else "left")
    if truth is not None:
        table.add_column("error px", justify="right")
    for d in result.leds:
        if d.pixel is not None:
            row = [
                str(d.led),
                f"{d.pixel[0]:.2f}",
                f"{d.pixel[1]:.2f}",
                f"{d.sigma_px:.3f}",
                f"{d.peak:.0f}",
                f"{d.snr:.0f}",
                "found",
            ]
        else:
            row = [str(d.led), "", "", "", "", "", escape(f"{d.failure}: {d.message}")]
        if truth is not None:
            ok = d.pixel is not None and np.isfinite(truth[d.led]).all()
            row.append(f"{np.linalg.norm(d.pixel - truth[d.led]):.3f}" if ok else "")
        table.add_row(*row)
    console.print(table)


def _write(
    out: Path,
    frames: list[NDArray],
    sequence: SwitchingSequence,
    result: LedDetections,
    truth: NDArray | None,
    console: Console,
    save_frames: bool,
) -> None:
    doc = {
        "sequence": sequence.pattern.astype(int).tolist(),
        "frame_gains": [float(g) for g in result.frame_gains],
        "changed_fraction": float(result.changed_fraction),
        "messages": list(result.messages),
        "leds": [
            {
                "led": d.led,
                "pixel": None if d.pixel is None else [float(c) for c in d.pixel],
                "sigma_px": None if d.pixel is None else float(d.sigma_px),
                "peak_dn": None if d.pixel is None else float(d.peak),
                "area_px": int(d.area),
                "snr": None if d.pixel is None else float(d.snr),
                "failure": None if d.failure is None else str(d.failure),
                "message": d.message,
                **(
                    {}
                    if truth is None
                    else {
                        "truth": [float(c) for c in truth[d.led]]
                        if np.isfinite(truth[d.led]).all()
                        else None
                    }
                ),
            }
            for d in result.leds
        ],
        "rejected": [
            {
                "led": r.led,
                "pixel": [float(c) for c in r.pixel],
                "area_px": int(r.area),
                "reasons": [str(x) for x in r.reasons],
            }
            for r in result.rejected
        ],
    }
    write_text_atomic(out / "detections.json", json.dumps(doc, indent=2) + "\n")
    lit = next(i for i, row in enumerate(sequence.pattern) if row.any())
    save_png(overlay(frames[lit], result, truth), out / "overlay.png")
    if save_frames:
        for i, frame in enumerate(frames):
            save_png(frame, out / f"frame_{i:02d}.png")
    console.print(f"wrote {out / 'detections.json'} and {out / 'overlay.png'}")


def overlay(
    image: NDArray, result: LedDetections, truth: NDArray | None, scale: int = 3
) -> NDArray:
    """The image enlarged ``scale`` times with each found LED marked (green cross and its
    index), each missing one listed, and the true pixels (red circles) when known."""
    import cv2

    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = (img.astype(float) / max(1.0, float(img.max())) * 255.0).astype(np.uint8)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    big = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    big = np.ascontiguousarray(big)

    def at(p: NDArray) -> tuple[int, int]:
        # Pixel centre u maps to scale * u + (scale - 1) / 2 in the enlarged image.
        return (round(scale * p[0] + 0.5 * (scale - 1)), round(scale * p[1] + 0.5 * (scale - 1)))

    if truth is not None:
        for p in truth:
            if np.isfinite(p).all():
                cv2.circle(big, at(p), 3 * scale, (255, 40, 40), 1, cv2.LINE_AA)
    missing = []
    for d in result.leds:
        if d.pixel is None:
            missing.append(f"LED {d.led}: {d.failure}")
            continue
        c = at(d.pixel)
        cv2.drawMarker(big, c, (40, 255, 40), cv2.MARKER_CROSS, 4 * scale, 1, cv2.LINE_AA)
        cv2.putText(
            big,
            str(d.led),
            (c[0] + 2 * scale, c[1] - 2 * scale),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.4,
            (40, 255, 40),
            1,
            cv2.LINE_AA,
        )
    for i, text in enumerate(missing):
        cv2.putText(
            big,
            text,
            (6, 16 + 16 * i),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            (255, 200, 40),
            1,
            cv2.LINE_AA,
        )
    return big
