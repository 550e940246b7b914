"""Speed of the MuJoCo world: physics steps per second of the paper's hall with the three
robots driving, and frames per second of each camera at 320 x 240.

Run: ``.venv/bin/python benchmarks/bench_world.py [--seconds S] [--frames N]``
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

from twin.scenario import load_scenario
from twin.sim.render import CameraRenderer
from twin.sim.world import build_world

# Imported after twin.sim, which chooses the headless OpenGL backend.
import mujoco  # isort: skip

ROOT = Path(__file__).resolve().parents[1]

# Goals of the three robots in scenarios/paper_hall.toml, m: straight lines that clear every
# obstacle, wall and each other (the benchmark checks that nothing collides).
DRIVES = {"parent": (40.0, 0.0), "child1": (10.0, 1.5), "child2": (-5.0, 8.0)}


def bench_physics(seconds: float) -> list[tuple[str, float, float]]:
    """(what, physics steps per wall second, real-time factor) for the paper's hall."""
    sc = load_scenario(ROOT / "scenarios" / "paper_hall.toml")
    rows = []
    world = build_world(sc)
    # All three robots drive on clear straight lines: the parent east along the route's
    # first leg (south of the island), child1 south-east towards the route, child2 west
    # along the north side (south of stairs_west, west of core_north).
    for name, goal in DRIVES.items():
        world.driving.drive(name, goal)
    world.run(0.5)  # warm-up
    ticks = round(seconds / world.control_period)
    t0 = time.perf_counter()
    world.step(ticks)
    wall = time.perf_counter() - t0
    steps = ticks * world.substeps
    sim = ticks * world.control_period
    moving = len(world.driving.moving())
    rows.append(
        (
            f"World.step, 3 robots driving ({moving} still moving at the end)",
            steps / wall,
            sim / wall,
        )
    )
    # The same state stepped by mujoco alone (no controllers, odometry or contact scan).
    m, d = world.model, world.data
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=steps)
    wall = time.perf_counter() - t0
    rows.append(("mj_step alone, same scene, last commands held", steps / wall, sim / wall))
    if world.driving.collisions:
        # A robot pushing against a wall is not the workload this benchmark measures.
        raise RuntimeError(
            "robots collided during the benchmark: "
            + ", ".join(
                f"{c.robot} with {c.other} at t = {c.time:.1f} s" for c in world.driving.collisions
            )
        )
    return rows


def bench_cameras(frames: int) -> list[tuple[str, float]]:
    """(camera, frames per second) at each camera's resolution, LEDs on, robots at rest."""
    sc = load_scenario(ROOT / "scenarios" / "paper_hall.toml")
    world = build_world(sc)
    world.run(0.2)
    for child in sc.robots.children:
        world.sensing.set_leds(child.name, True)
    rows = []
    with CameraRenderer(world) as r:
        for name in world.camera_names:
            for _ in range(3):
                r.render(name)
            t0 = time.perf_counter()
            for _ in range(frames):
                r.render(name)
            rows.append((name, frames / (time.perf_counter() - t0)))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds")
    parser.add_argument("--frames", type=int, default=100, help="frames per camera")
    args = parser.parse_args()
    print(
        f"mujoco {mujoco.__version__}, MUJOCO_GL={os.environ['MUJOCO_GL']}, "
        f"{platform.machine()}, {os.cpu_count()} CPU(s)"
    )
    print(f"\nPhysics: scenarios/paper_hall.toml, {args.seconds:g} s simulated, timestep 2 ms")
    print(f"{'what':<62} {'steps/s':>10} {'x real time':>12}")
    for what, sps, rtf in bench_physics(args.seconds):
        print(f"{what:<62} {sps:>10.0f} {rtf:>12.1f}")
    print(f"\nRendering: scenarios/paper_hall.toml, {args.frames} frames per camera, 320 x 240")
    print(f"{'camera':<8} {'frames/s':>10}")
    for name, fps in bench_cameras(args.frames):
        print(f"{name:<8} {fps:>10.1f}")


if __name__ == "__main__":
    main()
