"""Every command refuses a bad argument with a named error and exit code 2, and leaves
nothing behind: output paths that cannot hold the output, seeds out of range, numbers that
are not finite or out of range."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main

ROOT = Path(__file__).resolve().parents[3]
SMOKE = str(ROOT / "scenarios" / "smoke.toml")

COMMANDS = {
    "run": ["run", SMOKE, "--fidelity", "geometric", "--no-report", "--out"],
    "montecarlo": ["montecarlo", SMOKE, "--trials", "1", "--no-budget", "--out"],
    "detect": ["detect", "--scenario", SMOKE, "--camera", "cam1", "--out"],
    "render": ["render", SMOKE, "--camera", "cam1", "--out"],
    "scene": ["scene", SMOKE, "--export"],
}
FOLDERS = ("run", "montecarlo", "detect")


@pytest.fixture
def place(tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("the user's")
    full = tmp_path / "full"
    full.mkdir()
    (full / "notes.txt").write_text("the user's")
    return tmp_path, a_file, full


def _refused(args, capsys, *expected):
    assert main(args) == 2
    said = " ".join(capsys.readouterr().err.split())
    for text in expected:
        assert text in said, said
    assert "Traceback" not in said


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_an_output_under_a_file_is_refused(command, place, capsys):
    _, a_file, _ = place
    target = a_file / "sub" / ("x.png" if command in ("render", "scene") else "out")
    option = COMMANDS[command][-1]
    _refused([*COMMANDS[command], str(target)], capsys, option, f"lies under the file {a_file}")
    assert a_file.read_text() == "the user's"


@pytest.mark.parametrize("command", FOLDERS)
def test_an_output_folder_that_is_a_file_or_holds_other_things_is_refused(command, place, capsys):
    _, a_file, full = place
    _refused([*COMMANDS[command], str(a_file)], capsys, "is a file; expected a folder")
    _refused([*COMMANDS[command], str(full)], capsys, "is not empty (notes.txt)", "--overwrite")
    assert sorted(p.name for p in full.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("command", ["render", "scene"])
def test_an_output_file_that_is_a_folder_is_refused(command, place, capsys):
    _, _, full = place
    _refused([*COMMANDS[command], str(full)], capsys, "is a folder; expected the name of a file")


@pytest.mark.parametrize("command", ["run", "montecarlo", "detect"])
@pytest.mark.parametrize("seed", ["-1", "2.5", str(2**63)])
def test_a_seed_out_of_range_is_refused(command, seed, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_:
        main([*COMMANDS[command], str(out), "--seed", seed])
    assert exit_.value.code == 2
    assert "argument --seed: expected" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--distance", "-1", "expected a finite number above 0"),
        ("--distance", "nan", "expected a finite number above 0"),
        ("--at", "inf", "expected a finite number"),
        ("--saturation", "0", "expected a finite number above 0"),
        ("--leds", "0", "expected 1 to 64 (the most a switching sequence codes), got 0"),
    ],
)
def test_detect_refuses_numbers_out_of_range(option, value, expected, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([*COMMANDS["detect"], str(tmp_path / "out"), option, value])
    assert exit_.value.code == 2
    assert f"argument {option}: {expected}" in capsys.readouterr().err


def test_montecarlo_refuses_resume_and_overwrite_together(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([*COMMANDS["montecarlo"], str(tmp_path / "o"), "--resume", "--overwrite"])
    assert exit_.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["run", "scene", "montecarlo"])
def test_a_scenario_that_is_not_text_is_refused_in_one_line(command, tmp_path, capsys):
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(Path(SMOKE).read_bytes() + b"# caf\xe9\n")
    args = [a if a != SMOKE else str(bad) for a in COMMANDS[command]]
    _refused([*args, str(tmp_path / "out")], capsys, "is not UTF-8 text")


def test_render_refuses_an_image_name_that_is_not_png(tmp_path, capsys):
    out = tmp_path / "view.jpg"
    _refused([*COMMANDS["render"], str(out)], capsys, "--out", "give a .png file")
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (
            ["montecarlo", "S", "--trials", "1", "--workers", "2147483648"],
            "argument --workers: expected 1 to 4096 (processes or CPUs), got 2147483648",
        ),
        (
            ["detect", "a.png", "--leds", "1000"],
            "argument --leds: expected 1 to 64 (the most a switching sequence codes), got 1000",
        ),
    ],
)
def test_counts_past_what_a_command_can_hold_are_refused(argv, said, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    assert said in capsys.readouterr().err
