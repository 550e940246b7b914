"""Interruptions end a command cleanly: Ctrl-C and SIGTERM stop ``twin run`` with a word
on what was kept and exit code 130, its log closed; a Monte-Carlo run killed with -9
leaves none of its workers running."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from twin.interruption import EXIT_INTERRUPTED
from twin.record import read_log

ROOT = Path(__file__).resolve().parents[3]
HALL = ROOT / "scenarios" / "paper_hall.toml"
SMOKE = ROOT / "scenarios" / "smoke.toml"


def _wait_for(predicate, proc: subprocess.Popen, seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError("the command finished or hung before it could be interrupted")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_an_interrupted_run_says_so_and_closes_its_log(tmp_path, sig):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "twin.cli", "run", str(HALL), "--fidelity", "geometric"]
    cmd += ["--strategy", "paper", "--no-report", "--out", str(out)]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    log = out / "log.mcap"
    try:
        _wait_for(lambda: log.exists() and log.stat().st_size > 40_000, proc)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == EXIT_INTERRUPTED, stderr[-2000:]
    said = " ".join(stdout.split())
    assert f"the log of the run so far is {log}" in said
    assert "Traceback" not in stderr
    contents = read_log(log)
    assert contents.complete  # closed, not cut off
    assert "/total_station/shot" in contents.topics
    assert not (out / "results.json").exists()


def _alive_in_group(pgid: int) -> list[int]:
    """Processes of a process group that are still running (zombies do not count)."""
    alive = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        # pid (comm) state ppid pgrp ...: comm may hold spaces, so split after its ')'.
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(int(entry.name))
    return alive


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads the process table from /proc")
def test_workers_end_when_a_monte_carlo_run_is_killed(tmp_path):
    out = tmp_path / "mc"
    cmd = [sys.executable, "-m", "twin.cli", "montecarlo", str(SMOKE), "--trials", "40"]
    cmd += ["--workers", "2", "--no-budget", "--out", str(out)]
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group: the workers join it
    )
    pgid = proc.pid
    table = out / "trials.csv"
    try:
        _wait_for(lambda: table.exists() and table.read_text().count("\n") >= 2, proc)
        workers = [p for p in _alive_in_group(pgid) if p != proc.pid]
        assert len(workers) >= 2, "no worker was running"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and _alive_in_group(pgid):
            time.sleep(0.1)
        assert _alive_in_group(pgid) == [], "workers outlived their killed parent"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(pgid, signal.SIGKILL)  # whatever is left of the test's own run


def _interrupt(message: str):
    def raising(*_args, **_kwargs):
        raise KeyboardInterrupt(message) if message else KeyboardInterrupt

    return raising


@pytest.mark.parametrize(
    ("message", "reason"), [("", "Ctrl-C"), ("stopped by SIGTERM", "stopped by SIGTERM")]
)
def test_every_command_names_why_it_was_interrupted(tmp_path, monkeypatch, capsys, message, reason):
    import twin.cli.check
    import twin.cli.site
    import twin.montecarlo
    import twin.run.run_cameras
    import twin.run.runner
    from twin.cli import main

    # Wherever the interruption is caught, the reason is never empty.
    monkeypatch.setattr(twin.run.runner, "run_scenario", _interrupt(message))
    out = tmp_path / "run"
    assert main(["run", str(SMOKE), "--no-report", "--out", str(out)]) == EXIT_INTERRUPTED
    said = " ".join(capsys.readouterr().out.split())
    assert f"interrupted ({reason}): nothing was written; no results were computed" in said
    monkeypatch.setattr(twin.montecarlo, "run_montecarlo", _interrupt(message))
    out = tmp_path / "mc"
    assert main(["montecarlo", str(SMOKE), "--trials", "2", "--out", str(out)]) == 130
    said = " ".join(capsys.readouterr().out.split())
    assert f"interrupted ({reason}): the finished trials are in {out}; --resume continues" in said
    monkeypatch.setattr(twin.run.run_cameras, "latest_cameras", lambda *_: None)
    monkeypatch.setattr(twin.cli.check, "_check", _interrupt(message))
    out = tmp_path / "check"
    args = ["check", str(SMOKE), "--cameras", str(tmp_path), "--out", str(out)]
    assert main(args) == EXIT_INTERRUPTED
    said = " ".join(capsys.readouterr().out.split())
    assert f"interrupted ({reason}): nothing was written" in said
    # Where no command catches it, the command line does.
    monkeypatch.setattr(twin.cli.site, "run", _interrupt(message))
    args = ["site", str(tmp_path / "map.yaml"), "--cameras", "c.yaml", "--out", "x.toml"]
    assert main(args) == EXIT_INTERRUPTED
    assert capsys.readouterr().err.strip() == f"interrupted ({reason})"
