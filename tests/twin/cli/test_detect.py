"""``twin detect`` on the twin's frames and on image files, and its bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from twin.cli import main

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
LED_RANGE = SCENARIOS / "led_range.toml"


def test_detect_in_the_twin_then_on_the_saved_frames(tmp_path, capsys):
    out = tmp_path / "twin"
    code = main(
        [
            "detect",
            "--scenario",
            str(LED_RANGE),
            "--camera",
            "far",
            "--distance",
            "7",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "error px" in text
    doc = json.loads((out / "detections.json").read_text())
    leds = doc["leds"]
    assert [d["failure"] for d in leds] == [None] * 4
    for d in leds:
        assert np.linalg.norm(np.subtract(d["pixel"], d["truth"])) < 0.3
    assert cv2.imread(str(out / "overlay.png")).shape == (720, 960, 3)
    frames = sorted(out.glob("frame_*.png"))
    assert len(frames) == 6

    # The same frames as image files, as from a real camera: the same positions.
    files = tmp_path / "files"
    code = main(
        [
            "detect",
            *map(str, frames),
            "--sequence",
            "binary",
            "--led-line",
            "0.35",
            "0.65",
            "0.95",
            "1.25",
            "--out",
            str(files),
        ]
    )
    assert code == 0
    again = json.loads((files / "detections.json").read_text())["leds"]
    for a, b in zip(leds, again, strict=True):
        np.testing.assert_allclose(a["pixel"], b["pixel"], atol=1e-9)
        assert "truth" not in b


def test_an_led_out_of_view_is_reported_not_guessed(tmp_path, capsys):
    out = tmp_path / "near"
    # 3.2 m from the steep camera: the lowest LED falls below the image.
    assert (
        main(
            [
                "detect",
                "--scenario",
                str(LED_RANGE),
                "--camera",
                "near",
                "--distance",
                "3.2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    leds = json.loads((out / "detections.json").read_text())["leds"]
    assert leds[0]["failure"] == "not_in_view"
    assert leds[0]["pixel"] is None
    assert "not_in_view" in capsys.readouterr().out


def test_bad_inputs(tmp_path, capsys):
    img = tmp_path / "a.png"
    cv2.imwrite(str(img), np.zeros((20, 30, 3), np.uint8))
    small = tmp_path / "b.png"
    cv2.imwrite(str(small), np.zeros((10, 30, 3), np.uint8))
    cases = [
        (["detect", str(img)], "has 6 frames; got 1 image file"),
        (["detect", *[str(img)] * 5, str(tmp_path / "missing.png")], "no such image file"),
        (["detect", str(tmp_path / "none_*.png")], "no such image file"),
        (["detect"], "give the frames as image files, or --scenario"),
        (["detect", *[str(img)] * 5, str(tmp_path)], "no such image file"),
        (["detect", *[str(img)] * 5, str(small)], "differ in size"),
        (["detect", str(img), "--scenario", str(LED_RANGE), "--camera", "far"], "not both"),
        (["detect", "--scenario", str(LED_RANGE), "--camera", "cam9"], "expected one of near, far"),
        (
            ["detect", "--scenario", str(LED_RANGE), "--camera", "near", "--distance", "40"],
            "does not see",
        ),
        (
            ["detect", "--scenario", str(LED_RANGE), "--camera", "near", "--at", "1"],
            "X Y [YAW_DEG]",
        ),
        (["detect", *[str(img)] * 6, "--camera", "near"], "need --scenario"),
        (["detect", "--scenario", str(LED_RANGE)], "--scenario needs --camera: one of near"),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        assert message in capsys.readouterr().err, argv
    # A number out of range is refused by the argument's type, before anything runs.
    with pytest.raises(SystemExit) as exit_:
        main(["detect", "--leds", "0", str(img)])
    assert exit_.value.code == 2
    assert "argument --leds: expected 1 to 64" in capsys.readouterr().err


def test_detect_on_image_files_needs_no_opengl(tmp_path):
    # Reading, detecting and writing the overlay use OpenCV only: no mujoco import.
    import subprocess
    import sys

    frames = np.full((6, 40, 60, 3), 50, np.uint8)
    paths = []
    for i, f in enumerate(frames):
        paths.append(tmp_path / f"f{i}.png")
        cv2.imwrite(str(paths[-1]), f)
    code = (
        "import sys; from twin.cli import main; rc = main(sys.argv[1:]); "
        "assert 'mujoco' not in sys.modules, 'mujoco was imported'; sys.exit(rc)"
    )
    run = subprocess.run(
        [sys.executable, "-c", code, "detect", *map(str, paths), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        env={"MUJOCO_GL": "osmesa", "PATH": ""},
    )
    # Nothing lit in these frames: the detector runs, finds nothing, says so (exit 3).
    assert run.returncode == 3, run.stderr
    assert (tmp_path / "o" / "overlay.png").exists()
