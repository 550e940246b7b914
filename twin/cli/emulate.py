"""``twin emulate``: the twin plays the hardware over the devices' real protocols."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.table import Table

from twin.cli import arguments, live_server
from twin.cli.scene import load_or_report
from twin.outputs import check_file_target

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``emulate`` subcommand."""
    p = sub.add_parser(
        "emulate",
        help="serve a scenario's devices over their real protocols, for the drivers",
        description=(
            "Build the scenario's world and serve its devices as the hardware is reached: the "
            "total station as a Leica GeoCOM instrument on a pseudo-terminal, each Pioneer "
            "speaking ARCOS on a localhost TCP port (or a pseudo-terminal), each camera as an "
            "MJPEG stream over HTTP on localhost. Writes a rig file that points at them (and "
            "the world's truth beside it), then runs until stopped (Ctrl-C, SIGTERM). Then: "
            "twin devices RIG.toml; twin run SCENARIO --rig RIG.toml."
        ),
    )
    p.add_argument("scenario", type=Path, help="scenario file (.toml or .yaml)")
    p.add_argument(
        "--fidelity",
        choices=("geometric", "render"),
        default="geometric",
        help="geometric: LEDs drawn as spots at their projected places (default); render: "
        "rendered camera images",
    )
    p.add_argument("--seed", type=arguments.seed, help="root seed (default: the scenario's)")
    p.add_argument(
        "--time-scale",
        type=time_scale,
        default=10.0,
        metavar="X",
        help="emulated seconds per wall second, 1 (real time) to 1000; the rig file tells "
        "the drivers (default: 10)",
    )
    p.add_argument(
        "--links",
        choices=("tcp", "pty"),
        default="tcp",
        help="the robots' links: localhost TCP ports (default) or pseudo-terminals",
    )
    p.add_argument(
        "--fps", type=arguments.positive_float, default=30.0, help="camera frames per second"
    )
    p.add_argument(
        "--duration",
        type=arguments.positive_float,
        metavar="S",
        help="stop after S wall seconds (default: run until stopped)",
    )
    p.add_argument(
        "--rig-out",
        type=Path,
        required=True,
        metavar="RIG.toml",
        help="rig file to write (TOML; YAML for .yaml), and RIG.truth.json beside it",
    )
    live_server.add_live(
        p,
        "the emulated world's truth (the robots' and the instrument's true poses, the "
        "cameras as built, the site) as Foxglove's channels while it runs",
    )
    p.set_defaults(func=run)


def time_scale(text: str) -> float:
    """``--time-scale``: a number from :data:`twin.emulators.emulation.MIN_TIME_SCALE` to
    :data:`~twin.emulators.emulation.MAX_TIME_SCALE`."""
    from twin.emulators.emulation import check_time_scale

    value = arguments.finite_float(text)
    try:
        return check_time_scale(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("time scale: ")) from None


def run(args: argparse.Namespace) -> int:
    """Serve until stopped; exit code 0, 2 for bad input."""
    from twin.emulators.emulation import truth_file

    console = Console(highlight=False, soft_wrap=True)
    # Both files are checked before the work; a file the reader refuses is refused then.
    check_file_target(args.rig_out, "--rig-out")
    check_file_target(truth_file(args.rig_out), "--rig-out's truth file")
    sc = load_or_report(args.scenario, console)
    if sc is None or live_server.refused(args, console):
        return 2
    server = live_server.start_live(args, console) if args.live else None
    if args.live and server is None:
        return 2
    try:
        return _serve(args, sc, server, console)
    finally:
        if server is not None:
            live_server.stop_live(server, console)


def _serve(args: argparse.Namespace, sc: Any, live: LiveServer | None, console: Console) -> int:
    """Start the emulators and serve until stopped (or ``--duration``)."""
    from twin.emulators.emulation import start_emulation

    try:
        emulation = start_emulation(
            sc,
            fidelity=args.fidelity,
            seed=args.seed,
            time_scale=args.time_scale,
            links=args.links,
            camera_fps=args.fps,
        )
    except ValueError as exc:
        console.print(f"[red]error:[/red] {exc}", highlight=False)
        return 2
    with emulation:
        rig = emulation.write_rig_file(args.rig_out, "--rig-out")
        table = Table(title=f"{sc.name}: emulated devices ({args.fidelity}, x{args.time_scale:g})")
        table.add_column("device")
        table.add_column("protocol")
        table.add_column("address")
        table.add_row("total_station", "GeoCOM", emulation.total_station.address)
        for name, robot in emulation.robots.items():
            table.add_row(name, "ARCOS", robot.address)
        for name, server in emulation.cameras.items():
            table.add_row(name, "MJPEG over HTTP", server.url)
        console.print(table)
        console.print(f"rig file: {rig}  (stop with Ctrl-C)")
        witness = _live_witness(emulation, live) if live is not None else None
        start = time.monotonic()
        try:
            while args.duration is None or time.monotonic() - start < args.duration:
                if witness is not None:
                    with emulation.lock:
                        for name in emulation.robots:
                            witness.robot(name)
                        witness.instrument()
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
    console.print("emulators stopped")
    return 0


class _WorldTime:
    """The emulated world's clock (simulated seconds)."""

    def __init__(self, world: Any) -> None:
        self.world = world

    def now(self) -> float:
        return self.world.time


def _live_witness(emulation: Any, server: LiveServer) -> Any:
    """The world's truth, drawn and served live: the cameras as built now, the robots and
    the instrument as the caller asks (every 0.2 s)."""
    from twin.record.foxglove import FoxgloveStream
    from twin.record.foxglove.live import LiveRecorder
    from twin.sim.rig.truth import TruthWitness

    sc, sim = emulation.scenario, emulation.sim
    recorder = LiveRecorder(server, FoxgloveStream(sc))
    clock = _WorldTime(sim.world)
    witness = TruthWitness(recorder, sim.world, sim.frame, clock, sc.robots.parent.name)
    with emulation.lock:
        witness.cameras()
    return witness
