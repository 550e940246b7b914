"""``twin calibrate``: calibrate one camera from a file of 3D-2D correspondences."""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from calib import CalibrationResult, calibrate_opencv, calibrate_tsai
from calib.io import load_camera, read_points_csv, save_camera
from calib.io.camera_files import camera_format
from calib.io.points_csv import UNIT_SCALE
from calib.paper_units import kappa1_px2mm


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` subcommand."""
    p = sub.add_parser(
        "calibrate",
        help="calibrate one camera from a CSV of x,y,z,u,v correspondences",
        description=(
            "Calibrate one camera (Tsai's model by default) from 3D world points and their "
            "pixels. Prints the parameters with standard deviations and the paper's "
            "Table III metrics."
        ),
    )
    p.add_argument("points", type=Path, help="CSV with columns x,y,z,u,v (a header is allowed)")
    p.add_argument(
        "--image-size", nargs=2, type=int, required=True, metavar=("W", "H"), help="pixels"
    )
    p.add_argument("--units", choices=sorted(UNIT_SCALE), default="m", help="units of x,y,z")
    p.add_argument("--model", choices=["tsai", "opencv"], default="tsai")
    p.add_argument("--tangential", action="store_true", help="opencv model: also estimate p1, p2")
    p.add_argument("--k3", action="store_true", help="opencv model: also estimate k3")
    p.add_argument(
        "--pixel-size", type=float, metavar="MM", help="sensor pixel pitch (for kappa1 in 1/mm^2)"
    )
    p.add_argument(
        "--out",
        type=Path,
        help="write the camera: .json, .yaml (OpenCV) or .camera_info.yaml (ROS)",
    )
    p.add_argument("--json", type=Path, dest="json_out", help="write the result as JSON")
    p.add_argument(
        "--keep-duplicates",
        action="store_true",
        help="fit rows that repeat an earlier row exactly (same x,y,z,u,v) as independent "
        "measurements; by default they are merged, since a copy of a row is not a second "
        "measurement and counting it twice would shrink every standard deviation",
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
    }


def _fmt(v: float) -> str:
    """Four decimals, or four significant digits in e-notation for small numbers."""
    return f"{v:.4e}" if 0 < abs(v) < 1e-2 else f"{v:.4f}"


def print_result(console: Console, d: dict[str, Any], source: str) -> None:
    """Print the parameter and metric tables of a result dictionary."""
    units = d["units"]
    merged = f"; {d['duplicates']} duplicate rows merged" if d["duplicates_merged"] else ""
    t = Table(title=f"{d['model']} calibration of {source} ({d['n_points']} points{merged})")
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
        console.print(f"[yellow]note:[/yellow] {note}")


def run(args: argparse.Namespace) -> int:
    """Run ``twin calibrate``; returns the exit code (2 for bad input)."""
    console = Console()
    err = Console(stderr=True)
    try:
        if args.out is not None:
            camera_format(args.out)  # reject an unknown suffix before calibrating
        if args.pixel_size is not None and not args.pixel_size > 0:
            raise ValueError(f"--pixel-size must be positive, got {args.pixel_size}")
        points, pixels = read_points_csv(args.points, args.units)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # notes are printed with the result
            if args.model == "tsai":
                result = calibrate_tsai(
                    points, pixels, tuple(args.image_size), keep_duplicates=args.keep_duplicates
                )
            else:
                result = calibrate_opencv(
                    points,
                    pixels,
                    tuple(args.image_size),
                    tangential=args.tangential,
                    k3=args.k3,
                    keep_duplicates=args.keep_duplicates,
                )
    except ValueError as exc:
        err.print(f"[red]error:[/red] {exc}", highlight=False)
        return 2
    d = result_to_dict(result, args.units, args.pixel_size)
    print_result(console, d, str(args.points))
    if args.out is not None:
        save_camera(result.camera, args.out, name=args.points.stem)
        load_camera(args.out)  # what was written must read back
        console.print(f"camera written to {args.out}")
    if args.json_out is not None:
        args.json_out.parent.mkdir(parents=True, exist_ok=True)
        args.json_out.write_text(json.dumps(d, indent=2) + "\n")
        console.print(f"result written to {args.json_out}")
    return 0
