"""``--live``, ``--port`` and ``--host``: the Foxglove WebSocket server of ``twin run`` and
``twin emulate`` (:class:`twin.record.foxglove.live.LiveServer`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape

from twin.cli import arguments

if TYPE_CHECKING:
    from twin.record.foxglove.live import LiveServer


def add_live(parser: argparse.ArgumentParser, what: str) -> None:
    """Add ``--live``, ``--port`` and ``--host``; ``what`` says what is served."""
    parser.add_argument(
        "--live",
        action="store_true",
        help=f"serve over Foxglove's WebSocket protocol {what}; open ws://HOST:PORT in "
        "Foxglove. The server stops with the command",
    )
    parser.add_argument(
        "--port",
        type=arguments.number_in(int, 0, 65535, why="a TCP port; 0 picks a free one"),
        help="the --live server's port (default: 8765)",
    )
    parser.add_argument(
        "--host",
        help="the address the --live server listens on (default: 127.0.0.1, this machine only)",
    )


def refused(args: argparse.Namespace, console: Console) -> bool:
    """Whether ``--port`` or ``--host`` came without ``--live`` (said so)."""
    if not args.live and (args.port is not None or args.host is not None):
        console.print("[red]error:[/red] --port and --host apply to --live only")
        return True
    return False


def start_live(args: argparse.Namespace, console: Console) -> LiveServer | None:
    """The ``--live`` server, started; None (and the error shown) when it cannot listen."""
    from twin.record.foxglove.live import DEFAULT_HOST, DEFAULT_PORT, LiveServer

    host = args.host or DEFAULT_HOST
    port = DEFAULT_PORT if args.port is None else args.port
    try:
        server = LiveServer(host, port)
    except OSError as exc:
        console.print(f"[red]error:[/red] --port {port} (--host {host}): {escape(str(exc))}")
        return None
    console.print(f"serving live to Foxglove on ws://{host}:{server.port}")
    return server


def stop_live(server: LiveServer, console: Console) -> None:
    """Stop the server and say what it served."""
    server.close()
    console.print(
        f"live: {server.sent} Foxglove messages served, {server.dropped} dropped "
        "(the queue was full); server stopped"
    )
