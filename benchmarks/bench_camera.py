"""Rendered cameras and LED detection: the cost of an on/off image pair through the lens and
sensor models against a bare ``mujoco.Renderer.render()``, and the centroid error of the
detector against distance.

Run: ``.venv/bin/python benchmarks/bench_camera.py [--pairs N] [--samples N]``

Timing: for each camera of ``scenarios/paper_hall.toml`` (320 x 240, f about 770 px, Tsai
kappa1), the time of one LED-on/LED-off pair from :meth:`CameraSimulator.capture` (pinhole
render of the enlarged view, lens remap, pixel integration, blur, photon and read noise,
quantisation, ground truth) at supersampling 1, 2 and 4, divided by the time of two bare
renders at the camera's own resolution measured in the same run. The ratio is what the
camera model costs on top of MuJoCo's rasteriser, whatever the machine's speed.

Accuracy: ``scenarios/led_range.toml``, a child stood so that one LED is at each distance
(3 to 12 m) on a random image column, facing the camera; the binary switching sequence
(6 frames) with the default sensor noise; the detector's positions of every LED that is
whole and inside the image against the true pixels.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from calib.detection import SwitchingSequence, detect_leds
from twin.scenario import load_scenario
from twin.sim.capture import CameraSimulator
from twin.sim.placement import stand_for_led
from twin.sim.world import build_world

# Imported after twin.sim, which chooses the headless OpenGL backend.
import mujoco  # isort: skip

ROOT = Path(__file__).resolve().parents[1]
SUPERSAMPLING = (1, 2, 4)
DISTANCES = (3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0)
LED_HEIGHTS = (0.35, 0.65, 0.95, 1.25)


def bench_pairs(pairs: int) -> list[tuple[str, float, dict[int, float]]]:
    """(camera, ms per bare pair, {supersample: ms per captured pair}) for the hall."""
    sc = load_scenario(ROOT / "scenarios" / "paper_hall.toml")
    world = build_world(sc)
    world.run(0.2)
    rows = []
    with CameraSimulator(world) as sim:
        for name in world.camera_names:
            cid = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_CAMERA, name)
            w, h = (int(v) for v in world.model.cam_resolution[cid])
            with mujoco.Renderer(world.model, height=h, width=w) as bare:
                bare.update_scene(world.data, camera=cid)
                for _ in range(3):
                    bare.render()
                t0 = time.perf_counter()
                for _ in range(2 * pairs):
                    bare.update_scene(world.data, camera=cid)
                    bare.render()
                bare_ms = (time.perf_counter() - t0) / pairs * 1e3
            ours = {}
            for s in SUPERSAMPLING:
                sensor = sc.camera(name).sensor.model_copy(update={"supersample": s})
                for _ in range(2):
                    sim.capture(name, sensor)
                t0 = time.perf_counter()
                for _ in range(pairs):
                    for on in (True, False):
                        world.sensing.set_leds("child1", on)
                        sim.capture(name, sensor)
                ours[s] = (time.perf_counter() - t0) / pairs * 1e3
            rows.append((name, bare_ms, ours))
    return rows


def bench_accuracy(
    samples: int, supersample: int, seed: int = 0
) -> list[tuple[float, int, float, float, float]]:
    """(distance m, LEDs measured, RMS error px, max error px, mean predicted sigma px)."""
    sc = load_scenario(ROOT / "scenarios" / "led_range.toml")
    world = build_world(sc)
    marker = sc.marker.assembly()
    rng = np.random.default_rng(seed)
    seq = SwitchingSequence.binary(4)
    rows = []
    with CameraSimulator(world, seed=seed) as sim:
        for distance in DISTANCES:
            errors, sigmas = [], []
            for _ in range(samples):
                led = int(rng.integers(0, 4))
                placed = None
                for camera in ("near", "far"):
                    cam = world.camera(camera)
                    placed = stand_for_led(
                        cam, marker.leds_body[led], sc.space.floor_z, distance, rng.uniform(30, 290)
                    )
                    if placed is not None:
                        break
                if placed is None:
                    continue
                world.place("child1", *placed)
                sensor = sc.camera(camera).sensor.model_copy(update={"supersample": supersample})
                frames = sim.capture_sequence(camera, "child1", seq, sensor=sensor)
                found = detect_leds([f.image for f in frames], seq, led_line=LED_HEIGHTS)
                t = frames[0].truth("child1")[led]
                d = found.leds[led]
                w, h = cam.image_size
                if not (t.visible and 4 <= t.pixel[0] <= w - 5 and 4 <= t.pixel[1] <= h - 5):
                    continue
                if not d.found:
                    errors.append(np.array([np.inf, np.inf]))
                    continue
                errors.append(d.pixel - t.pixel)
                sigmas.append(d.sigma_px)
            if not errors:
                rows.append((distance, 0, float("nan"), float("nan"), float("nan")))
                continue
            e = np.linalg.norm(np.array(errors), axis=1)
            rows.append(
                (
                    distance,
                    len(e),
                    float(np.sqrt(np.mean(e**2))),
                    float(e.max()),
                    float(np.mean(sigmas)) if sigmas else float("nan"),
                )
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=30, help="on/off pairs per camera")
    parser.add_argument("--samples", type=int, default=12, help="LED placements per distance")
    args = parser.parse_args()
    print(
        f"mujoco {mujoco.__version__}, MUJOCO_GL={os.environ.get('MUJOCO_GL')}, "
        f"{platform.machine()}, {os.cpu_count()} CPU(s)"
    )
    print(
        f"\nOne LED on/off image pair, scenarios/paper_hall.toml, 320 x 240, {args.pairs} pairs;"
        "\nratio = captured pair / two bare mujoco.Renderer.render() calls, same run"
    )
    head = f"{'camera':<7} {'bare [ms]':>10}"
    for s in SUPERSAMPLING:
        head += f" {f'ss{s} [ms]':>10} {f'ss{s} ratio':>10}"
    print(head)
    for name, bare, ours in bench_pairs(args.pairs):
        line = f"{name:<7} {bare:>10.1f}"
        for s in SUPERSAMPLING:
            line += f" {ours[s]:>10.1f} {ours[s] / bare:>10.2f}"
        print(line)
    for s in (1, 2):
        print(
            f"\nCentroid error vs distance, scenarios/led_range.toml, binary sequence, default "
            f"noise, supersample {s}, {args.samples} placements per distance"
        )
        print(f"{'dist [m]':>8} {'LEDs':>5} {'RMS [px]':>9} {'max [px]':>9} {'sigma [px]':>11}")
        for distance, n, rms, worst, sigma in bench_accuracy(args.samples, s):
            print(f"{distance:>8.1f} {n:>5d} {rms:>9.3f} {worst:>9.3f} {sigma:>11.4f}")


if __name__ == "__main__":
    main()
