"""How few points does ``twin check`` need? Stops per camera against the chi-square test's
false-alarm and detection rates and the re-posed camera's accuracy, on the smoke room at
the geometric fidelity.

Each of ``--runs`` calibrations (``twin run``, seeds 1, 2, ...) is checked, for each number
of stops, with the camera unmoved, shifted 2 cm along x and turned 0.2 deg about its own y
axis (pan), each check with noise of its own. Printed per number of stops:

- false alarms among the unmoved checks (at the default false-alarm rate, 1e-3) and the
  mean chi2 / dof there (1 when the noise model is right);
- the detection rate of the 2 cm shift and the 0.2 deg turn;
- the re-posed camera's error against the truth (position, mm; rotation, deg; RMS over the
  moved checks) and the mean of its squared position error in units of its predicted
  covariance (3 when the prediction is right: 3 degrees of freedom);
- the error of the estimated move (re-posed minus calibrated) against the move the twin
  made (2 cm, or 0.2 deg): shift, mm, and turn, deg, RMS over the moved checks.

The last line gives the calibrations' own errors (70 points each) for comparison.

    .venv/bin/python benchmarks/bench_check.py [--runs 10] [--stops 2 3 4 5 6 8 12]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from calib.rotation import rotation_angle_between
from twin.campaign.check import check_cameras
from twin.run.run_cameras import latest_cameras
from twin.run.runner import built_markers, check_noise_seed, run_scenario
from twin.scenario import load_scenario
from twin.scenario.schema import Faults, MovedCamera
from twin.sim.rig import build_sim_rig
from twin.sim.world import build_world

ROOT = Path(__file__).resolve().parents[1]
CAMERA = "cam1"
MOVES = {
    "unmoved": None,
    "shift 2 cm": MovedCamera(camera=CAMERA, shift=(0.02, 0.0, 0.0)),
    "turn 0.2 deg": MovedCamera(camera=CAMERA, turn_deg=(0.0, 0.2, 0.0)),
}


def moved(sc, fault):
    """The scenario with its camera moved by ``fault`` (None: as it is)."""
    faults = Faults() if fault is None else Faults(moved_cameras=(fault,))
    return sc.model_copy(update={"faults": faults})


def one_check(sc, calibrated, stops, noise_seed):
    """(the check's verdict on the camera, the true camera in W)."""
    world = build_world(sc, markers=built_markers(sc))
    sim = build_sim_rig(world, "geometric", seed=noise_seed)
    try:
        truth = sim.frame.camera(world.camera(CAMERA))
        outcome = check_cameras(
            sim.rig,
            sc,
            {CAMERA: calibrated.camera},
            covariances={CAMERA: calibrated.covariance},
            stops=stops,
        )
    finally:
        sim.close()
    return outcome.checks.get(CAMERA), truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--stops", type=int, nargs="+", default=[2, 3, 4, 5, 6, 8, 12])
    args = parser.parse_args()
    base = load_scenario(ROOT / "scenarios" / "smoke.toml")
    t0 = time.perf_counter()
    rows = {
        s: {
            "fa": [],
            "chi": [],
            "det": {k: [] for k in MOVES},
            "pos": [],
            "rot": [],
            "maha": [],
            "shift": [],
            "turn": [],
        }
        for s in args.stops
    }
    cal_pos, cal_rot = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.runs):
            sc = base.model_copy(update={"seed": r + 1})
            out = Path(tmp) / f"run{r}"
            run_scenario(sc, out, fidelity="geometric", report=False)
            calibrated = latest_cameras(out / "cameras", sc)[CAMERA]
            for stops in args.stops:
                row = rows[stops]
                for k, (name, fault) in enumerate(MOVES.items()):
                    seed = check_noise_seed(1000 * r + 10 * stops + k)
                    check, truth = one_check(moved(sc, fault), calibrated, stops, seed)
                    if check is None:
                        continue
                    if fault is None and stops == args.stops[0]:
                        cal_pos.append(np.linalg.norm(calibrated.camera.position - truth.position))
                        cal_rot.append(
                            rotation_angle_between(calibrated.camera.world2cam_r, truth.world2cam_r)
                        )
                    if fault is None:
                        row["fa"].append(check.moved)
                        row["chi"].append(check.consistency.chi2 / check.consistency.dof)
                    row["det"][name].append(check.moved)
                    new = check.repose
                    if fault is None or new is None:
                        continue
                    err = new.camera.position - truth.position
                    cov = new.camera_covariance[8:, 8:]
                    row["pos"].append(np.linalg.norm(err))
                    row["maha"].append(float(err @ np.linalg.solve(cov, err)))
                    row["rot"].append(
                        rotation_angle_between(new.camera.world2cam_r, truth.world2cam_r)
                    )
                    row["shift"].append(np.linalg.norm(new.shift_m - np.asarray(fault.shift)))
                    turn = np.radians(fault.turn_deg)
                    row["turn"].append(np.linalg.norm(new.turn_rad - turn))

    def rms(v):
        return float(np.sqrt(np.mean(np.square(v)))) if len(v) else float("nan")

    print(
        f"smoke room, geometric fidelity, {args.runs} calibrations, false-alarm rate 1e-3 "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    head = (
        "stops points  false alarms  chi2/dof  detect 2cm  detect 0.2deg  pos err mm  "
        "rot err deg  err^2/pred  move err mm  deg"
    )
    print(head)
    for stops, row in rows.items():
        fa = f"{sum(row['fa'])}/{len(row['fa'])}"
        det = [f"{sum(v)}/{len(v)}" for k, v in row["det"].items() if k != "unmoved"]
        print(
            f"{stops:5d} {4 * stops:6d}  {fa:>12}  {np.mean(row['chi']):8.2f}  {det[0]:>10}  "
            f"{det[1]:>13}  {rms(row['pos']) * 1e3:10.1f}  {np.degrees(rms(row['rot'])):11.3f}  "
            f"{np.mean(row['maha']):10.2f}  {rms(row['shift']) * 1e3:11.1f}  "
            f"{np.degrees(rms(row['turn'])):.3f}"
        )
    print(
        f"calibration (70 points): pos err {rms(cal_pos) * 1e3:.1f} mm, rot err "
        f"{np.degrees(rms(cal_rot)):.3f} deg (RMS)"
    )


if __name__ == "__main__":
    main()
