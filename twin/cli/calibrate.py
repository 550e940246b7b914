"""``twin calibrate``: calibrate one camera from a file of 3D-2D correspondences.

Every bad input ends with a message that names the argument and what was expected, and
exit code 2: the arguments are checked when parsed, the output paths before the
calibration, and the output files are written whole or not at all
(:mod:`twin.outputs`).
"""

from __future__ import annotations

import argparse
import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from calib import CalibrationResult, calibrate_opencv, calibrate_tsai
from calib.checks import MAX_IMAGE_SIDE_PX
from calib.handedness import (
    AXES,
    MirroredFrameError,
    camera_axes,
    is_poor_fit,
    mirror_explains,
    mirror_hints,
    mirror_points,
)
from calib.io import load_camera, read_points_csv, save_camera
from calib.io.camera_files import camera_format
from calib.io.points_csv import PIXEL_ORIGINS, UNIT_SCALE, pixels_to_opencv
from calib.paper_units import kappa1_px2mm
from twin.cli import arguments
from twin.cli.calibrate_notes import DEFAULT_UNITS, cli_notes, mirror_note, mirrored_message
from twin.outputs import OutputError, OutputFiles, check_file_target

# Pixel pitches accepted by --pixel-size, mm. Real sensors range from about 0.56 um (phone
# cameras) to about 200 um (X-ray flat panels); the bounds leave a factor of 5 beyond both,
# and reject a pitch given in micrometres (most are 1.1 to 200) instead of millimetres.
MIN_PITCH_MM = 1e-4
MAX_PITCH_MM = 1.0


_image_side = arguments.number_in(int, 1, MAX_IMAGE_SIDE_PX, unit="pixels")
"""argparse type of --image-size: a whole number of pixels, 1 to MAX_IMAGE_SIDE_PX."""

_pixel_pitch = arguments.number_in(
    float, MIN_PITCH_MM, MAX_PITCH_MM, unit="mm", why="a pixel pitch: a 5 um pitch is 0.005"
)
"""argparse type of --pixel-size: a pixel pitch in mm, MIN_PITCH_MM to MAX_PITCH_MM."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` subcommand."""
    p = sub.add_parser(
        "calibrate",
        help="calibrate one camera from a CSV of x,y,z,u,v correspondences",
        description=(
            "Calibrate one camera (Tsai's model by default) from 3D world points and their "
            "pixels. Prints the parameters with standard deviations and the paper's "
            "Table III metrics, and the notes a user should read: rows that were exact "
            "copies of others (merged), and warnings when the result is implausible for its "
            "input (a camera kilometres from its points: the wrong --units)."
        ),
    )
    p.add_argument(
        "points",
        type=Path,
        help="CSV file with columns x,y,z,u,v, one row per point (required; a header row "
        "and a byte-order mark are allowed)",
    )
    p.add_argument(
        "--image-size",
        nargs=2,
        type=_image_side,
        required=True,
        metavar=("W", "H"),
        help="width and height of the image the pixels were measured in, px (required: no default)",
    )
    p.add_argument(
        "--units",
        choices=sorted(UNIT_SCALE),
        default=DEFAULT_UNITS,
        help="unit of x,y,z in the file: m (metres) or mm (millimetres) (default: m). "
        "Lengths in the output are in the same unit. A file read in the wrong unit "
        "calibrates with every length 1000 times off, which is warned about",
    )
    p.add_argument(
        "--model",
        choices=["tsai", "opencv"],
        default="tsai",
        help="camera model: Tsai's (f, cx, cy, sx, kappa1) or OpenCV's (fx, fy, cx, cy, k1, "
        "k2, ...) (default: tsai)",
    )
    p.add_argument(
        "--tangential",
        action="store_true",
        help="with --model opencv: also estimate p1, p2 (default: off, fixed at 0)",
    )
    p.add_argument(
        "--k3",
        action="store_true",
        help="with --model opencv: also estimate k3 (default: off, fixed at 0)",
    )
    p.add_argument(
        "--pixel-size",
        type=_pixel_pitch,
        metavar="MM",
        help="with --model tsai: sensor pixel pitch, mm, to also report kappa1 in 1/mm^2 "
        "(default: none; kappa1 in 1/px^2 only)",
    )
    p.add_argument(
        "--out",
        type=Path,
        metavar="FILE",
        help="write the camera to this file: .json, .yaml (OpenCV) or .camera_info.yaml "
        "(ROS) (default: not written)",
    )
    p.add_argument(
        "--json",
        type=Path,
        dest="json_out",
        metavar="FILE",
        help="write the result, with its notes, to this JSON file (default: not written)",
    )
    p.add_argument(
        "--keep-duplicates",
        action="store_true",
        help="fit rows that repeat an earlier row exactly (same x,y,z,u,v) as independent "
        "measurements (default: off: they are merged and counted, since a copy of a row is "
        "not a second measurement and counting it twice would shrink every standard "
        "deviation)",
    )
    p.add_argument(
        "--mirror-axis",
        choices=AXES,
        help="the world frame is left-handed with this axis reversed: negate it before "
        "calibrating; the position and camera axes are reported in the file's frame, the "
        "rotation and --out in the mirrored, right-handed one (default: none)",
    )
    p.add_argument(
        "--pixel-origin",
        choices=PIXEL_ORIGINS,
        default="top-left",
        help="where v = 0 is: top-left (OpenCV's, v down) or bottom-left (v up; turned into "
        "(H - 1) - v with H from --image-size) (default: top-left)",
    )
    p.add_argument(
        "--one-based",
        action="store_true",
        help="u, v count pixels from 1 (MATLAB's convention): 1 is subtracted from both, "
        "before --pixel-origin is applied (default: off, counted from 0)",
    )
    p.set_defaults(func=run)


def result_to_dict(
    result: CalibrationResult, units: str, pixel_size_mm: float | None
) -> dict[str, Any]:
    """Machine-readable result; lengths in ``units``, angles in degrees."""
    scale = 1.0 / UNIT_SCALE[units]
    par, std, cov = result.parameters, result.std_by_name, result.covariance
    names = result.parameter_names
    params: dict[str, Any] = {}
    stds: dict[str, Any] = {}
    if result.model == "tsai":
        for key in ("f_px", "cx", "cy", "sx", "kappa1_px"):
            params[key], stds[key] = par[key], std[key]
        if pixel_size_mm:
            params["kappa1_mm"] = kappa1_px2mm(par["kappa1_px"], pixel_size_mm)
            stds["kappa1_mm"] = kappa1_px2mm(std["kappa1_px"], pixel_size_mm)
    else:
        fx, fy = par["fx"], par["fy"]
        i, j = names.index("fx"), names.index("fy")
        grad = np.array([1.0 / fy, -fx / fy**2])
        var_sx = grad @ cov[np.ix_([i, j], [i, j])] @ grad
        params.update(f_px=fy, sx=fx / fy)
        stds.update(f_px=std["fy"], sx=float(np.sqrt(var_sx)))
        for key in names[: names.index("rx")]:
            params[key], stds[key] = par[key], std[key]
    params["rotation_deg"] = np.degrees([par["rx"], par["ry"], par["rz"]]).tolist()
    stds["rotation_deg"] = np.degrees([std["rx"], std["ry"], std["rz"]]).tolist()
    params["position"] = (np.array([par["x"], par["y"], par["z"]]) * scale).tolist()
    stds["position"] = (np.array([std["x"], std["y"], std["z"]]) * scale).tolist()
    m = result.metrics
    return {
        "model": result.model,
        "units": units,
        "image_size": list(result.camera.image_size),
        "n_points": result.n_points,
        "duplicates": result.duplicates,
        "duplicates_merged": bool(result.duplicates) and not result.duplicates_kept,
        "dof": result.dof,
        "sigma_px": result.sigma_px,
        "parameters": params,
        "std": stds,
        "metrics": {
            "pixel_error_mean": m.pixel.mean,
            "pixel_error_rms": m.pixel.rms,
            "pixel_error_std": m.pixel.std,
            "pixel_error_max": m.pixel.max,
            "error_3d_mean": m.error_3d.mean * scale,
            "error_3d_rms": m.error_3d.rms * scale,
            "error_3d_std": m.error_3d.std * scale,
            "error_3d_max": m.error_3d.max * scale,
        },
        "notes": list(result.notes),
        "warnings": [],
    }


def _json_ready(value: Any) -> Any:
    """``value`` with every NaN or infinity replaced by None (JSON has neither)."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def result_json(d: dict[str, Any]) -> str:
    """A result dictionary as strict JSON: a value that is not finite (the std of a
    parameter the data do not determine) is written as null."""
    return json.dumps(_json_ready(d), indent=2, allow_nan=False) + "\n"


def _fmt(v: float) -> str:
    """Four decimals, or four significant digits in e-notation for small numbers."""
    return f"{v:.4e}" if 0 < abs(v) < 1e-2 else f"{v:.4f}"


def print_result(console: Console, d: dict[str, Any], source: str) -> None:
    """Print the parameter and metric tables of a result dictionary."""
    units = d["units"]
    n_dup = d["duplicates"]
    merged = f"; {n_dup} duplicate row{'s' * (n_dup > 1)} merged" if d["duplicates_merged"] else ""
    title = f"{d['model']} calibration of {source} ({d['n_points']} points{merged})"
    t = Table(title=escape(title))
    t.add_column("parameter")
    t.add_column("value", justify="right")
    t.add_column("std", justify="right")
    t.add_column("unit")
    unit_of = {"kappa1_px": "1/px^2", "kappa1_mm": "1/mm^2", "sx": "", "f_px": "px"}
    for key, value in d["parameters"].items():
        if isinstance(value, list):
            labels = ("about X", "about Y", "about Z") if key == "rotation_deg" else ("x", "y", "z")
            unit = "deg" if key == "rotation_deg" else units
            for lab, v, s in zip(labels, value, d["std"][key], strict=True):
                t.add_row(f"{key.split('_')[0]} {lab}", _fmt(v), _fmt(s), unit)
        else:
            unit = unit_of.get(key, "px" if key in ("cx", "cy", "fx", "fy") else "")
            t.add_row(key, _fmt(value), _fmt(d["std"][key]), unit)
    console.print(t)
    m = d["metrics"]
    mt = Table(title="Table III metrics on the calibration data")
    for col in ("metric", "mean", "rms", "std", "max", "unit"):
        mt.add_column(col, justify="right" if col not in ("metric", "unit") else "left")
    for name, unit in (("pixel_error", "px"), ("error_3d", units)):
        mt.add_row(name, *(_fmt(m[f"{name}_{s}"]) for s in ("mean", "rms", "std", "max")), unit)
    console.print(mt)
    console.print(f"residual sigma {d['sigma_px']:.4f} px, {d['dof']} degrees of freedom")
    for note in d["notes"]:
        if note in d["warnings"]:
            console.print(f"[bold yellow]warning:[/bold yellow] {escape(note)}", highlight=False)
        else:
            console.print(f"[yellow]note:[/yellow] {escape(note)}", highlight=False)


def _check_model_options(args: argparse.Namespace) -> None:
    """Reject options that the chosen model would ignore."""
    ignored = {
        "--tangential": args.tangential and args.model != "opencv",
        "--k3": args.k3 and args.model != "opencv",
        "--pixel-size": args.pixel_size is not None and args.model != "tsai",
    }
    for option, bad in ignored.items():
        if bad:
            wanted = "tsai" if option == "--pixel-size" else "opencv"
            raise ValueError(
                f"{option} has no effect with --model {args.model}; expected it with "
                f"--model {wanted} only"
            )


def _check_outputs(args: argparse.Namespace) -> None:
    """Reject, before any work, output paths that cannot be written or would destroy the
    input; the message names the option."""
    outputs = {"--out": args.out, "--json": args.json_out}
    for option, path in outputs.items():
        if path is None:
            continue
        check_file_target(path, option)
        if path.resolve() == args.points.resolve():
            raise OutputError(
                f"{option} {path}: is the points file; expected another file (writing it "
                "would destroy the input)"
            )
        if option == "--out":
            try:
                camera_format(path)
            except ValueError as exc:
                raise OutputError(f"--out {exc}") from None
    both = args.out is not None and args.json_out is not None
    if both and args.out.resolve() == args.json_out.resolve():
        raise OutputError(
            f"--out {args.out} and --json {args.json_out} name the same file; expected two files"
        )


def _calibrate(
    args: argparse.Namespace, points: np.ndarray, pixels: np.ndarray
) -> tuple[CalibrationResult, list[warnings.WarningMessage]]:
    """Calibrate with the chosen model; also return the warnings emitted meanwhile."""
    size = tuple(args.image_size)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.model == "tsai":
            result = calibrate_tsai(points, pixels, size, keep_duplicates=args.keep_duplicates)
        else:
            result = calibrate_opencv(
                points,
                pixels,
                size,
                tangential=args.tangential,
                k3=args.k3,
                keep_duplicates=args.keep_duplicates,
            )
    return result, [w for w in caught if issubclass(w.category, UserWarning)]


def _write_outputs(args: argparse.Namespace, result: CalibrationResult, d: dict) -> list[str]:
    """Write --out and --json, all or nothing; returns what to print about them."""
    written = []
    with OutputFiles() as files:
        if args.out is not None:

            def write_camera(tmp: Path) -> None:
                save_camera(result.camera, tmp, name=args.points.stem)
                load_camera(tmp)  # what was written must read back

            files.stage(args.out, "--out", write_camera)
            written.append(f"camera written to {args.out}")
        if args.json_out is not None:
            text = result_json(d)
            files.stage(args.json_out, "--json", lambda tmp: tmp.write_text(text))
            written.append(f"result written to {args.json_out}")
    return written


def _input_pixels(args: argparse.Namespace, pixels: np.ndarray) -> np.ndarray:
    """The file's pixels in OpenCV's convention: --one-based first, then --pixel-origin."""
    height = args.image_size[1] if args.image_size is not None else None
    if args.pixel_origin == "bottom-left" and height is None:
        raise ValueError(
            "--pixel-origin bottom-left needs the image height: give --image-size W H "
            "(v is turned into (H - 1) - v); expected a known height"
        )
    return pixels_to_opencv(
        pixels, origin=args.pixel_origin, one_based=args.one_based, height=height
    )


def _calibrate_checked(
    args: argparse.Namespace, points: np.ndarray, pixels: np.ndarray
) -> tuple[CalibrationResult, list[warnings.WarningMessage]]:
    """:func:`_calibrate`, and when it fails or fits poorly, a try of the mirror image.

    Points that fit only mirrored raise :class:`MirroredFrameError` naming the option to
    use (``--mirror-axis``, or ``--pixel-origin``: a turned-over image is a mirror image);
    otherwise the calibration's own error is raised, or its poor result returned. One
    mirror (x) is enough: every mirror image fits equally well (:mod:`calib.handedness`).
    """
    failure: ValueError | None = None
    rms: float | None = None
    try:
        result, caught = _calibrate(args, points, pixels)
    except ValueError as exc:
        failure = exc
    else:
        rms = result.metrics.pixel.rms
        if not is_poor_fit(rms):
            return result, caught
    try:
        mirrored, _ = _calibrate(args, mirror_points(points, "x"), pixels)
    except ValueError:
        mirrored = None
    if mirrored is not None and mirror_explains(rms, mirrored.metrics.pixel.rms):
        problem = str(failure) if failure else f"the fit is poor (pixel RMS {rms:.3g} px)"
        centre = mirror_points(mirrored.camera.position, "x")
        raise MirroredFrameError(
            mirrored_message(
                problem,
                mirror_hints(centre, points),
                mirrored.metrics.pixel.rms,
                args.mirror_axis,
                args.pixel_origin,
            )
        )
    if failure is not None:
        raise failure
    return result, caught


def add_input_conventions(
    d: dict[str, Any], result: CalibrationResult, args: argparse.Namespace
) -> None:
    """Record the pixel and frame options in a result dictionary, and with --mirror-axis
    give the position and camera axes in the file's frame.

    Adds ``mirror_axis``, ``pixel_origin``, ``one_based`` and ``camera_axes`` (unit
    directions of image right, image down and the optical axis in the file's frame). With
    a mirror axis, ``parameters.position`` is mapped back to the file's frame, and the
    rotation (which a left-handed frame has none of) moves to ``mirrored_frame`` with the
    position there: the camera written by --out is that one.
    """
    axis = args.mirror_axis
    d["mirror_axis"], d["pixel_origin"], d["one_based"] = axis, args.pixel_origin, args.one_based
    d["camera_axes"] = {
        k: v.tolist() for k, v in camera_axes(result.camera.world2cam_r, axis).items()
    }
    if axis is None:
        return
    par, std = d["parameters"], d["std"]
    d["mirrored_frame"] = {
        "axis": axis,
        "rotation_deg": par.pop("rotation_deg"),
        "rotation_deg_std": std.pop("rotation_deg"),
        "position": par["position"],
    }
    par["position"] = mirror_points(par["position"], axis).tolist()
    d["notes"].append(mirror_note(axis))


def print_mirrored(console: Console, d: dict[str, Any]) -> None:
    """Print the camera axes in the file's frame and the rotation in the mirrored one."""
    axis = d["mirror_axis"]
    t = Table(title=f"camera axes in the file's frame (left-handed: {axis} reversed)")
    for col in ("axis", "x", "y", "z"):
        t.add_column(col, justify="left" if col == "axis" else "right")
    for name, v in d["camera_axes"].items():
        t.add_row(name.replace("_", " "), *(f"{c:.4f}" for c in v))
    console.print(t)
    rot = ", ".join(f"{v:.4f}" for v in d["mirrored_frame"]["rotation_deg"])
    console.print(
        f"rotation about X, Y, Z in the mirrored, right-handed frame ({axis} negated; the "
        f"frame of --out): {rot} deg",
        highlight=False,
    )


def run(args: argparse.Namespace) -> int:
    """Run ``twin calibrate``; returns the exit code (2 for bad input)."""
    console = Console(soft_wrap=True)
    err = Console(stderr=True, soft_wrap=True)
    try:
        _check_model_options(args)
        _check_outputs(args)
        points, pixels = read_points_csv(args.points, args.units)
        pixels = _input_pixels(args, pixels)
        points = mirror_points(points, args.mirror_axis)
        result, caught = _calibrate_checked(args, points, pixels)
        d = result_to_dict(result, args.units, args.pixel_size)
        d["notes"], d["warnings"] = cli_notes(result, args.units, caught)
        add_input_conventions(d, result, args)
        print_result(console, d, str(args.points))
        if d["mirror_axis"] is not None:
            print_mirrored(console, d)
        for line in _write_outputs(args, result, d):
            console.print(escape(line), highlight=False)
    except ValueError as exc:
        err.print(f"[red]error:[/red] {escape(str(exc))}", highlight=False, soft_wrap=True)
        return 2
    return 0
