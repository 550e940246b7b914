"""The ``twin`` command line: one subcommand per module in this package.

Each subcommand module defines ``register(subparsers)``, which adds its parser and sets
``func`` to a callable taking the parsed arguments and returning the exit code.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from rich.console import Console

from twin.interruption import EXIT_INTERRUPTED, interruptible, interruption_reason
from twin.outputs import OutputError

# Subcommand modules of this package, in the order ``twin --help`` lists them.
_COMMANDS = [
    "calibrate",
    "scene",
    "render",
    "detect",
    "run",
    "check",
    "montecarlo",
    "strategies",
    "site",
    "emulate",
    "devices",
    "replay",
]


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="twin",
        description="Digital twin for calibrating a camera network with mobile robots.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in _COMMANDS:
        importlib.import_module(f"twin.cli.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``twin`` console script; returns the process exit code: 0, 2 for
    bad input (a named error, nothing written), 130 when interrupted (Ctrl-C, SIGTERM,
    SIGHUP), or the command's own (see its help)."""
    args = build_parser().parse_args(argv)
    err = Console(stderr=True, highlight=False, soft_wrap=True)
    try:
        with interruptible():
            return int(args.func(args) or 0)
    except KeyboardInterrupt as exc:
        err.print(f"interrupted ({interruption_reason(exc)})", markup=False)
        return EXIT_INTERRUPTED
    except OutputError as exc:
        err.print(f"error: {exc}", markup=False)
        return 2


if __name__ == "__main__":
    sys.exit(main())
