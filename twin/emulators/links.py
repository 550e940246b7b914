"""The byte links an emulated device answers on: a pseudo-terminal (what a USB-serial
adapter looks like to the driver) or a localhost TCP port (a serial-to-Ethernet bridge,
the Pioneer simulators' port). The driver opens :attr:`Link.address` with pyserial's
``serial_for_url`` either way."""

from __future__ import annotations

import contextlib
import os
import pty
import select
import socket
import termios
import threading
import tty
from abc import abstractmethod

from twin.closing import Closing


class Link(Closing):
    """One device end of a byte link. Reading and writing may happen in different threads."""

    @property
    @abstractmethod
    def address(self) -> str:
        """What a driver opens: a pty's path, or ``socket://127.0.0.1:PORT``."""

    @abstractmethod
    def read(self, size: int, timeout: float) -> bytes:
        """Up to ``size`` bytes the driver sent, waiting at most ``timeout`` wall seconds;
        b"" when nothing came (or no driver is connected)."""

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Send ``data`` to the driver (dropped when none is connected)."""

    @abstractmethod
    def drop(self) -> None:
        """Break the connection as a device that is unplugged does (the driver sees its
        link fail); a TCP link accepts a new connection afterwards."""


class PtyLink(Link):
    """A pseudo-terminal in raw mode: the device holds the master side, the driver opens
    :attr:`address` (the slave's path) as a serial port."""

    def __init__(self) -> None:
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        attrs = termios.tcgetattr(self._slave)
        attrs[3] &= ~termios.ECHO
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)
        self._path = os.ttyname(self._slave)
        self._write_lock = threading.Lock()
        self._closed = False

    @property
    def address(self) -> str:
        return self._path

    def read(self, size: int, timeout: float) -> bytes:
        if self._closed:
            return b""
        try:
            ready, _, _ = select.select([self._master], [], [], max(timeout, 0.0))
            return os.read(self._master, size) if ready else b""
        except (OSError, ValueError):
            return b""

    def write(self, data: bytes) -> None:
        with self._write_lock:
            view = memoryview(data)
            while view and not self._closed:
                try:
                    n = os.write(self._master, view)
                except OSError:
                    return
                view = view[n:]

    def drop(self) -> None:
        self.close()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class TcpLink(Link):
    """A TCP port on localhost that accepts one driver at a time.

    Args:
        port: the port (0: one the system chooses, see :attr:`port`).
    """

    def __init__(self, port: int = 0) -> None:
        self._server = socket.create_server(("127.0.0.1", port))
        self._server.setblocking(False)
        self.port = self._server.getsockname()[1]
        self._client: socket.socket | None = None
        self._lock = threading.Lock()
        self._closed = False

    @property
    def address(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    def _accept(self, timeout: float) -> socket.socket | None:
        ready, _, _ = select.select([self._server], [], [], max(timeout, 0.0))
        if not ready:
            return None
        try:
            client, _ = self._server.accept()
        except (BlockingIOError, OSError):
            return None
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            self._client = client
        return client

    def read(self, size: int, timeout: float) -> bytes:
        if self._closed:
            return b""
        client = self._client
        try:
            if client is None:
                client = self._accept(timeout)
                if client is None:
                    return b""
            ready, _, _ = select.select([client], [], [], max(timeout, 0.0))
            if not ready:
                return b""
            data = client.recv(size)
        except (OSError, ValueError):
            data = b""
            ready = [client]
        if not data and ready:
            self._forget(client)  # the driver hung up
        return data

    def write(self, data: bytes) -> None:
        with self._lock:
            client = self._client
            if client is None:
                return
            try:
                client.sendall(data)
            except OSError:
                self._client = None

    def _forget(self, client: socket.socket | None) -> None:
        with self._lock:
            if client is not None and self._client is client:
                self._client = None
        if client is not None:
            with contextlib.suppress(OSError):
                client.close()

    def drop(self) -> None:
        client = self._client
        if client is not None:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
            self._forget(client)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self.drop()
        self._server.close()
