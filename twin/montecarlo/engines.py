"""Where trials run: a process pool on this machine, or Ray tasks on a local Ray instance
or an existing cluster.

An engine maps a function over items and yields the results as they finish (in no fixed
order); the caller sorts what it keeps. Items are taken from their iterable as workers
free up (a few per worker in flight), so a run of any length holds only those in memory.
``close()`` stops what is still running.
"""

from __future__ import annotations

import itertools
import multiprocessing
import os
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

ENGINES = ("local", "ray")

RAY_MISSING = (
    "--engine ray needs Ray, an optional extra: pip install 'camnet-twin[cluster]' "
    "(or pip install 'ray>=2.9')"
)


PARENT_POLL = 0.5
"""How often a worker checks that the process that started it is still there, s."""


def watch_parent(parent_pid: int) -> None:
    """Make this process end when ``parent_pid`` is no longer its parent (it was killed,
    with -9 say, and this process was handed to another): a daemon thread checks every
    :data:`PARENT_POLL` seconds. The pool's workers run it as they start, so that none is
    left running, orphaned, after its parent is gone."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


class LocalEngine:
    """A pool of ``workers`` processes on this machine (one worker: in this process).

    Workers are started with ``spawn`` (a fresh interpreter, safe with MuJoCo's OpenGL);
    at most twice as many items as workers are in flight, so an interrupt loses little.
    Workers end with their parent (:func:`watch_parent`), and an interrupt ends the ones
    at work at once instead of waiting for their trials.
    """

    def __init__(self, workers: int = 1) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.workers = workers
        self._pool: ProcessPoolExecutor | None = None

    def imap_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        if self.workers == 1:
            for item in items:
                yield fn(item)
            return
        ctx = multiprocessing.get_context("spawn")
        self._pool = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=ctx,
            initializer=watch_parent,
            initargs=(os.getpid(),),
        )
        pending: set[Future] = set()
        todo = iter(items)
        try:
            for item in todo:
                pending.add(self._pool.submit(fn, item))
                if len(pending) >= 2 * self.workers:
                    break
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in done:
                    nxt = next(todo, None)
                    if nxt is not None:
                        pending.add(self._pool.submit(fn, nxt))
                    yield f.result()
        except BaseException:
            self._terminate()
            raise
        finally:
            self.close()

    def _terminate(self) -> None:
        """End the workers now (an interrupt or an error: their trials are not wanted)."""
        if self._pool is None:
            return
        # ProcessPoolExecutor has no public way to end its workers before Python 3.14's
        # terminate_workers(); its table of processes is the way round.
        processes = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(timeout=5)
        self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


RAY_CONNECT_TIMEOUT = 5.0
"""Seconds to wait for a Ray cluster's address to accept a connection before giving up
(Ray itself keeps trying for minutes)."""

_RAY_DEFAULT_PORTS = {"ray://": 10001, "": 6379}


def check_ray_address(address: str, timeout_s: float = RAY_CONNECT_TIMEOUT) -> None:
    """Refuse, within ``timeout_s``, a Ray address that nothing answers at.

    ``address`` is ``host:port`` (a cluster's GCS, port 6379 by default), ``ray://host:port``
    (Ray Client, port 10001 by default), or ``auto`` / ``local`` (not checked: Ray resolves
    them itself).

    Raises:
        ValueError: an address that is not of these forms.
        RuntimeError: nothing accepts a connection there, naming the address and the cause.
    """
    if address in ("auto", "local"):
        return
    scheme = "ray://" if address.startswith("ray://") else ""
    rest = address[len(scheme) :]
    host, sep, port_text = rest.rpartition(":")
    if not sep:
        host, port_text = rest, str(_RAY_DEFAULT_PORTS[scheme])
    if not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(
            f"Ray address {address!r}: expected host:port, ray://host:port, auto or local"
        )
    try:
        with socket.create_connection((host.strip("[]"), int(port_text)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise RuntimeError(
            f"no Ray cluster answers at {address} ({exc}; waited at most {timeout_s:g} s): "
            "start one there with `ray start --head`, or give --ray-address auto on a node "
            "of a running cluster"
        ) from exc


class RayEngine:
    """Ray tasks: on a new local Ray instance of ``workers`` CPUs, or on the cluster at
    ``address`` (``auto`` for the one this machine belongs to).

    At most twice as many tasks as the cluster has CPUs are submitted at a time. The
    cluster's nodes need this package installed (the same version). A Ray instance
    this engine started is shut down by :meth:`close`; one it joined is left running.
    """

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(RAY_MISSING) from exc
        self.ray = ray
        self._started = False
        if address is not None:
            check_ray_address(address)
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {
                "include_dashboard": False,
                "log_to_driver": False,
                "configure_logging": False,
            }
            if address is None:
                kwargs["num_cpus"] = workers or os.cpu_count() or 1
            ray.init(address=address, **kwargs)
            self._started = True

    def imap_unordered(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        remote = self.ray.remote(num_cpus=1, max_retries=2)(fn)
        cpus = int(self.ray.cluster_resources().get("CPU", 1))
        todo = iter(items)
        refs = [remote.remote(item) for item in itertools.islice(todo, 2 * max(cpus, 1))]
        try:
            while refs:
                done, refs = self.ray.wait(refs, num_returns=1)
                refs.extend(remote.remote(item) for item in itertools.islice(todo, 1))
                yield self.ray.get(done[0])
        finally:
            for ref in refs:
                self.ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._started and self.ray.is_initialized():
            self.ray.shutdown()
            self._started = False


def engine_check(name: str, address: str | None = None) -> None:
    """Refuse an unknown engine, or an address with the local engine, before anything
    starts.

    Raises:
        ValueError: naming the problem.
    """
    if name not in ENGINES:
        raise ValueError(f"unknown engine {name!r}; choose one of {', '.join(ENGINES)}")
    if name == "local" and address is not None:
        raise ValueError("--ray-address goes with --engine ray")


def make_engine(name: str, workers: int = 1, address: str | None = None) -> Any:
    """The engine called ``name`` (``local`` or ``ray``).

    Raises:
        ValueError: for an unknown engine, or an address with the local engine.
        RuntimeError: for ``ray`` when Ray is not installed (saying how to install it).
    """
    engine_check(name, address)
    if name == "local":
        return LocalEngine(workers)
    return RayEngine(workers, address)
