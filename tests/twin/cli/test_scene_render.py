"""``twin scene`` and ``twin render`` on good and bad scenarios."""

from __future__ import annotations

from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from twin.cli import build_parser, main

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
SMOKE = SCENARIOS / "smoke.toml"


def _bad(tmp_path: Path) -> Path:
    text = SMOKE.read_text(encoding="utf-8").replace(
        "[[space.obstacles]]", "[[space.obstacels]]", 1
    )
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_subcommands_are_registered():
    parser = build_parser()
    args = parser.parse_args(["render", str(SMOKE), "--camera", "cam1", "--out", "x.png"])
    assert args.leds == "off"
    args = parser.parse_args(["scene", str(SMOKE)])
    assert args.export is None


def test_scene_prints_a_summary_and_exports(tmp_path, capsys):
    out = tmp_path / "export" / "smoke.xml"
    assert main(["scene", str(SMOKE), "--export", str(out)]) == 0
    text = capsys.readouterr().out
    for word in (
        "parent",
        "child1",
        "child2",
        "pioneer3at",
        "cam1",
        "route",
        "4.00 m",
        "floor view",
    ):
        assert word in text
    model = mujoco.MjModel.from_xml_path(str(out))
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "cam1") >= 0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "parent/instrument") >= 0


def test_scene_rejects_a_bad_scenario(tmp_path, capsys):
    bad = _bad(tmp_path)
    out = tmp_path / "never.xml"
    assert main(["scene", str(bad), "--export", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err
    assert "space.obstacels: unknown key" in err
    assert not out.exists()  # nothing runs on a scenario that fails validation


@pytest.mark.parametrize("pinhole", [True, False])
def test_render_writes_an_image_and_the_leds_show(tmp_path, capsys, pinhole):
    off, on = tmp_path / "off.png", tmp_path / "on.png"
    extra = ["--pinhole"] if pinhole else []
    assert main(["render", str(SMOKE), "--camera", "cam1", "--out", str(off), *extra]) == 0
    assert (
        main(["render", str(SMOKE), "--camera", "cam1", "--leds", "on", "--out", str(on), *extra])
        == 0
    )
    text = capsys.readouterr().out
    assert "320 x 240" in text
    assert ("pinhole" in text) == pinhole
    a, b = cv2.imread(str(off)), cv2.imread(str(on))
    assert a.shape == (240, 320, 3)
    # Only the LEDs change: a lit LED adds hundreds of DN summed over the channels; the
    # sensor noise of two frames (about 3.4 DN a channel) passes 60 in no pixel of 76800.
    diff = np.abs(a.astype(int) - b.astype(int)).sum(axis=2)
    assert 0 < (diff > 60).sum() < 500


@pytest.mark.parametrize("camera", ["cam9"])
def test_render_rejects_an_unknown_camera(tmp_path, capsys, camera):
    out = tmp_path / "x.png"
    assert main(["render", str(SMOKE), "--camera", camera, "--out", str(out)]) == 2
    assert "expected one of cam1" in capsys.readouterr().err
    assert not out.exists()


def test_render_rejects_a_bad_scenario(tmp_path, capsys):
    out = tmp_path / "x.png"
    assert main(["render", str(_bad(tmp_path)), "--camera", "cam1", "--out", str(out)]) == 2
    assert "unknown key" in capsys.readouterr().err
    assert not out.exists()
