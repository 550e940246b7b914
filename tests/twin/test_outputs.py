"""One run per output folder: a folder is claimed with a manifest and an OS lock, refused
when it holds something else or another process holds it, cleared of what the command
owns when the user overwrites it; files are replaced whole or not at all."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from twin.outputs import (
    LOCK,
    MANIFEST,
    OutputError,
    check_file_target,
    check_folder,
    claim_folder,
    read_manifest,
    write_text_atomic,
)

OWNS = ("results.json", "cameras", "frame_*.png")
ROOT = Path(__file__).resolve().parents[2]
MC = ("trials.csv",)

HOLDER = """
import sys
from twin.outputs import claim_folder
folder = claim_folder(sys.argv[1], "montecarlo", ("trials.csv",))
(folder.path / "trials.csv").write_text("rows")
print("held", flush=True)
sys.stdin.read()
"""
"""A process that claims the folder ``argv[1]`` for a Monte-Carlo run, says so, and holds
it until its stdin closes (or it is killed)."""


def _hold(folder: Path) -> subprocess.Popen:
    """Start a process that holds ``folder``; returns once it does."""
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(folder)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        cwd=ROOT,
    )
    line = holder.stdout.readline()
    assert line == b"held\n", line + holder.stdout.read()
    return holder


@pytest.fixture
def holders():
    """Start processes that hold folders (``holders(folder)``); each is stopped by its
    handle after the test."""
    started: list[subprocess.Popen] = []

    def start(folder: Path) -> subprocess.Popen:
        started.append(_hold(folder))
        return started[-1]

    try:
        yield start
    finally:
        for p in started:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=10)
            p.stdin.close()
            p.stdout.close()


def test_a_new_folder_is_claimed_with_a_manifest(tmp_path):
    folder = claim_folder(tmp_path / "a" / "b", "run", OWNS, {"seed": 3})
    manifest = read_manifest(folder.path)
    assert manifest["command"] == "run"
    assert manifest["arguments"] == {"seed": 3}
    assert manifest["complete"] is False
    folder.finished(calibrations=5)
    assert read_manifest(folder.path)["complete"] is True
    assert read_manifest(folder.path)["calibrations"] == 5


def test_a_folder_that_holds_a_run_is_refused_and_kept(tmp_path):
    claim_folder(tmp_path, "run", OWNS).finished()
    (tmp_path / "results.json").write_text("{}")
    with pytest.raises(
        OutputError, match=r"--out .*: holds a finished `twin run` run .*--overwrite"
    ):
        claim_folder(tmp_path, "run", OWNS)
    assert (tmp_path / "results.json").read_text() == "{}"


def test_another_commands_folder_or_a_users_files_are_refused(tmp_path):
    first = claim_folder(tmp_path / "mc", "montecarlo", ("trials.csv",))
    with pytest.raises(OutputError, match=r"holds an unfinished `twin montecarlo` run"):
        claim_folder(tmp_path / "mc", "run", OWNS)
    assert first.held  # a refused claim of this process leaves the folder to the first
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match=r"is not empty \(notes\.txt\)"):
        claim_folder(tmp_path / "mine", "run", OWNS)


def test_overwrite_clears_what_the_command_owns_and_nothing_else(tmp_path):
    claim_folder(tmp_path, "run", OWNS)
    (tmp_path / "results.json").write_text("old")
    (tmp_path / "cameras").mkdir()
    (tmp_path / "cameras" / "cam1.json").write_text("old")
    (tmp_path / "frame_00.png").write_bytes(b"old")
    (tmp_path / "notes.txt").write_text("the user's")
    folder = claim_folder(tmp_path, "run", OWNS, {"seed": 4}, overwrite=True)
    # The lock file is there while the run lasts, and gone with it.
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([LOCK, MANIFEST, "notes.txt"])
    assert read_manifest(tmp_path)["arguments"] == {"seed": 4}
    folder.finished()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([MANIFEST, "notes.txt"])


def test_resume_continues_only_the_commands_own_run(tmp_path):
    claim_folder(tmp_path / "mc", "montecarlo", ("trials.csv",))
    (tmp_path / "mc" / "trials.csv").write_text("rows")
    resumed = claim_folder(tmp_path / "mc", "montecarlo", ("trials.csv",), resume=True)
    assert resumed.resumed
    assert (tmp_path / "mc" / "trials.csv").read_text() == "rows"
    with pytest.raises(OutputError, match=r"holds a `twin montecarlo` run, not one of `twin run`"):
        claim_folder(tmp_path / "mc", "run", OWNS, resume=True)
    with pytest.raises(OutputError, match="holds no `twin montecarlo` run to resume"):
        claim_folder(tmp_path / "none", "montecarlo", ("trials.csv",), resume=True)
    assert not (tmp_path / "none").exists()


def test_paths_that_cannot_hold_the_output_are_named(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(OutputError, match=r"--out .*a_file: is a file; expected a folder"):
        claim_folder(a_file, "run", OWNS)
    with pytest.raises(OutputError, match=r"lies under the file .*a_file; expected a folder"):
        claim_folder(a_file / "sub", "run", OWNS)
    with pytest.raises(OutputError, match=r"--export .*: is a folder; expected the name of a"):
        check_file_target(tmp_path, "--export")
    with pytest.raises(OutputError, match=r"--json .*: lies under the file .*a_file; expected"):
        check_file_target(a_file / "x.json", "--json")
    assert a_file.read_text() == "x"


def test_an_atomic_write_leaves_the_old_file_whole_when_it_fails(tmp_path, monkeypatch):
    path = tmp_path / "results.json"
    write_text_atomic(path, json.dumps({"run": 1}))

    def killed(*_):
        raise KeyboardInterrupt  # interrupted between writing and renaming

    with monkeypatch.context() as m:
        m.setattr(os, "replace", killed)
        with pytest.raises(KeyboardInterrupt):
            write_text_atomic(path, json.dumps({"run": 2}))
    assert json.loads(path.read_text()) == {"run": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]  # no temporary left
    write_text_atomic(path, json.dumps({"run": 2}))
    assert json.loads(path.read_text()) == {"run": 2}


def test_a_run_folder_holds_one_run(tmp_path):
    from twin.cli import main

    # The smoke scenario without its reference data set (half a run's time; what the folder
    # holds does not depend on it).
    smoke = tmp_path / "smoke.toml"
    text = (Path(__file__).resolve().parents[2] / "scenarios" / "smoke.toml").read_text()
    smoke.write_text(text + "\n[campaign]\nreference_cameras = []\n")
    out = tmp_path / "run"
    base = ["run", str(smoke), "--fidelity", "geometric", "--out", str(out)]
    assert main([*base, "--seed", "1"]) == 0
    assert (out / "report.md").exists()
    assert main([*base, "--seed", "2", "--no-report"]) == 2  # refused: it holds a run
    assert json.loads((out / "results.json").read_text())["seed"] == 1
    assert main([*base, "--seed", "2", "--no-report", "--overwrite"]) == 0
    assert json.loads((out / "results.json").read_text())["seed"] == 2
    # The first run's report, figures and cameras are gone with it.
    assert not (out / "report.md").exists()
    assert not (out / "figures").exists()
    assert read_manifest(out)["arguments"]["seed"] == 2


@pytest.mark.parametrize("seed", [-1, 2**63, 1.5])
def test_a_run_refuses_a_seed_out_of_range_before_writing(tmp_path, seed):
    from twin.run.runner import run_scenario

    smoke = Path(__file__).resolve().parents[2] / "scenarios" / "smoke.toml"
    with pytest.raises(ValueError, match=r"a seed must be a whole number from 0 to 2\^63 - 1"):
        run_scenario(smoke, tmp_path / "run", fidelity="geometric", seed=seed)
    assert not (tmp_path / "run").exists()


def _listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_a_folder_another_process_holds_is_refused_whatever_the_options(
    tmp_path, holders, monkeypatch
):
    monkeypatch.setattr("twin.outputs.LOCK_PATIENCE", 0.0)  # no look of another to wait out
    out = tmp_path / "mc"
    holder = holders(out)
    before = _listing(out)
    assert json.loads(before[LOCK])["pid"] == holder.pid
    in_use = rf"--out {out}: in use by another `twin montecarlo` run \(process {holder.pid} "
    for options in ({}, {"overwrite": True}, {"resume": True}):
        with pytest.raises(OutputError, match=in_use):
            claim_folder(out, "montecarlo", MC, **options)
        with pytest.raises(OutputError, match=in_use):
            claim_folder(out, "run", OWNS, overwrite=True)
        # A command that checks first and claims when its work is done is refused before it.
        with pytest.raises(OutputError, match=in_use):
            check_folder(out, "detect", ("detections.json",), **options)
    assert _listing(out) == before  # nothing written, nothing removed
    holder.stdin.close()  # the holder ends without finishing its run: the lock goes with it
    assert holder.wait(timeout=10) == 0
    claim_folder(out, "montecarlo", MC, resume=True).release()
    assert not (out / LOCK).exists()


@pytest.mark.parametrize("again", ["resume", "overwrite"])
def test_a_killed_runs_lock_does_not_block_its_folder(tmp_path, holders, again):
    out = tmp_path / "mc"
    holder = holders(out)
    holder.send_signal(signal.SIGKILL)
    holder.wait(timeout=10)
    assert json.loads((out / LOCK).read_text())["pid"] == holder.pid  # left behind
    # Not "something else in the folder", and not a run to refuse: the lock is free.
    with pytest.raises(OutputError, match=r"holds an unfinished `twin montecarlo` run"):
        check_folder(out, "montecarlo", MC)
    folder = claim_folder(out, "montecarlo", MC, **{again: True})
    assert folder.held
    assert json.loads((out / LOCK).read_text())["pid"] == os.getpid()
    assert (out / "trials.csv").exists() == (again == "resume")
    folder.finished()
    assert not (out / LOCK).exists()
    assert not folder.held


def test_a_folder_holding_only_a_stale_lock_file_is_empty(tmp_path):
    (tmp_path / LOCK).write_text('{"pid": 1, "command": "run"}\n')
    check_folder(tmp_path, "run", OWNS)
    with claim_folder(tmp_path, "run", OWNS) as folder:
        assert folder.held
        assert LOCK in read_manifest(tmp_path)["owns"]
    assert not folder.held
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST]


def test_a_run_that_took_the_folder_since_it_was_checked_is_not_overwritten(tmp_path, monkeypatch):
    import twin.outputs as outputs

    out = tmp_path / "run"
    make_folder = outputs._make_folder

    def another_run_meanwhile(*args) -> None:
        # Between the check and the lock: another run claims the folder, writes, finishes.
        make_folder(*args)
        monkeypatch.setattr(outputs, "_make_folder", make_folder)
        claim_folder(out, "run", OWNS, {"seed": 1}).finished()
        (out / "results.json").write_text("theirs")

    # A command that checks first and claims once its work is done (twin detect).
    check_folder(out, "detect", ("detections.json",))
    monkeypatch.setattr(outputs, "_make_folder", another_run_meanwhile)
    with pytest.raises(OutputError, match=r"holds a finished `twin run` run"):
        claim_folder(out, "detect", ("detections.json", "results.json"), {"seed": 2})
    assert (out / "results.json").read_text() == "theirs"
    assert read_manifest(out)["arguments"] == {"seed": 1}
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "results.json"])


def test_a_second_twin_run_into_a_held_folder_exits_2_naming_the_holder(tmp_path, holders, capsys):
    from twin.cli import main

    out = tmp_path / "run"
    holder = holders(out)
    before = _listing(out)
    smoke = ROOT / "scenarios" / "smoke.toml"
    args = ["run", str(smoke), "--fidelity", "geometric", "--out", str(out), "--overwrite"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"{out}: in use by another `twin montecarlo` run (process {holder.pid}" in err
    assert _listing(out) == before
