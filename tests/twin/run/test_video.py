"""``twin run --video``: a video of the run drawn from its log, the route and the cameras'
frustums on it; bad options are named before anything is written."""

from __future__ import annotations

from contextlib import nullcontext
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from twin.cli import main
from twin.record import read_log
from twin.run import video

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"
PERIOD_S = 40.0


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, Path, int]:
    tmp = tmp_path_factory.mktemp("video")
    out, mp4 = tmp / "run", tmp / "run.mp4"
    args = ["run", str(SMOKE), "--fidelity", "geometric", "--seed", "5", "--no-report"]
    code = main([*args, "--out", str(out), "--video", str(mp4), "--video-period", str(PERIOD_S)])
    return out, mp4, code


def frames(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, frame = cap.read()
        if not ok:
            return out
        out.append(frame)


def test_the_video_has_a_frame_per_period_of_the_campaign(run):
    out, mp4, code = run
    assert code == 0
    end = read_log(out / "log.mcap").messages[-1].timestamp
    got = frames(mp4)
    assert len(got) == int(end // PERIOD_S) + 1
    assert got[0].shape == (video.SIZE[1], video.SIZE[0], 3)


def test_the_frustums_as_built_and_as_calibrated_are_drawn(run):
    last = frames(run[1])[-1].astype(int)
    b, g, r = last[..., 0], last[..., 1], last[..., 2]
    built = (g > 150) & (r < 100) & (b < 120)  # (0.1, 0.8, 0.2)
    calibrated = (b > 180) & (r < 110) & (g < 160)  # (0.2, 0.4, 1.0) and the route
    assert built.sum() > 50
    assert calibrated.sum() > 50


@given(st.floats(0.0, 1e6))
def test_the_default_period_keeps_the_video_short(duration):
    period = video.default_period(duration)
    assert period >= video.MIN_PERIOD_S
    assert (duration // period + 1) / video.FPS <= video.MAX_VIDEO_S + 1 / video.FPS


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        (["--video", "v.avi"], "--video"),
        (["--video-period", "5"], "--video-period applies to --video only"),
        (["--video", "v.mp4", "--rig", "rig.toml"], "--video applies to the twin"),
        (["--video", "v.mp4", "--video-period", "0"], "--video-period"),
    ],
)
def test_bad_video_options_are_named_and_nothing_is_written(tmp_path, capsys, extra, said):
    out = tmp_path / "run"
    extra = [str(tmp_path / e) if e.startswith(("v.", "rig")) else e for e in extra]
    # argparse refuses a period of 0 itself (exit 2 naming the option).
    with pytest.raises(SystemExit) if extra[-1] == "0" else nullcontext():
        code = main(["run", str(SMOKE), "--out", str(out), *extra])
        assert code == 2
    captured = capsys.readouterr()
    assert said in captured.out + captured.err
    assert not out.exists()
    assert not list(tmp_path.glob("*.mp4"))
    assert not list(tmp_path.glob("*.avi"))


def test_a_video_that_cannot_be_rendered_is_named_and_not_left(tmp_path, monkeypatch, capsys):
    import argparse

    from rich.console import Console

    from twin.cli import run as run_cli
    from twin.sim.gl import RenderBackendError

    def fails(sc, log, out, **kwargs):
        Path(out).write_bytes(b"half a video")
        raise RenderBackendError("cannot render offscreen (MUJOCO_GL=egl): no display")

    monkeypatch.setattr(video, "render_video", fails)
    mp4 = tmp_path / "v.mp4"
    args = argparse.Namespace(video=mp4, video_period=None, seed=None)
    assert not run_cli._write_video(args, object(), tmp_path / "log.mcap", Console(soft_wrap=True))
    assert f"--video {mp4}: cannot render offscreen" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
