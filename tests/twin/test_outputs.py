"""One run per output folder: a folder is claimed with a manifest, refused when it holds
something else, cleared of what the command owns when the user overwrites it; files are
replaced whole or not at all."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from twin.outputs import (
    MANIFEST,
    OutputError,
    check_file_target,
    claim_folder,
    read_manifest,
    write_text_atomic,
)

OWNS = ("results.json", "cameras", "frame_*.png")


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
    claim_folder(tmp_path / "mc", "montecarlo", ("trials.csv",))
    with pytest.raises(OutputError, match=r"holds an unfinished `twin montecarlo` run"):
        claim_folder(tmp_path / "mc", "run", OWNS)
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
    claim_folder(tmp_path, "run", OWNS, {"seed": 4}, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([MANIFEST, "notes.txt"])
    assert read_manifest(tmp_path)["arguments"] == {"seed": 4}


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

    smoke = Path(__file__).resolve().parents[2] / "scenarios" / "smoke.toml"
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
    from twin.runner import run_scenario

    smoke = Path(__file__).resolve().parents[2] / "scenarios" / "smoke.toml"
    with pytest.raises(ValueError, match=r"a seed must be a whole number from 0 to 2\^63 - 1"):
        run_scenario(smoke, tmp_path / "run", fidelity="geometric", seed=seed)
    assert not (tmp_path / "run").exists()
