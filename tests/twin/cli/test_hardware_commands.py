"""``twin devices``, ``twin run --rig`` and ``twin emulate`` at the command line: what a
user sees first on real hardware, and the named errors of bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from calib.io.camera_files import save_camera
from twin.cli import main
from twin.emulators.emulation import start_emulation
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"


@pytest.fixture
def emulation():
    em = start_emulation(SMOKE, time_scale=30.0, camera_fps=100.0)
    try:
        yield em
    finally:
        em.close()


def test_devices_lists_what_every_device_said_and_the_leds_a_camera_saw(
    emulation, tmp_path, capsys
):
    rig = emulation.write_rig_file(tmp_path / "rig.toml")
    assert main(["devices", str(rig)]) == 0
    out = capsys.readouterr().out
    assert "total station total_station: name TS16 R500; serial 1234567" in out
    for robot, model in (("parent", "p3at"), ("child1", "p3dx"), ("child2", "p3dx")):
        assert f"robot {robot}: name {robot}; type Pioneer; subtype {model}-sh; battery_v" in out
    assert "camera cam1:" in out
    assert "resolution (320, 240)" in out
    # The children stand where cam1 sees them at the start: a blink shows every LED.
    assert "LEDs child1: found 4 of 4" in out
    assert "LEDs child2: found 4 of 4" in out
    # Nothing moved and every session was closed.
    for name, robot in emulation.robots.items():
        assert not robot.body.moving, name
        assert not robot.session_open, name


def test_devices_reports_a_device_that_does_not_answer(emulation, tmp_path, capsys):
    rig = emulation.write_rig_file(tmp_path / "rig.toml")
    text = rig.read_text().replace(emulation.robots["child2"].address, "socket://127.0.0.1:9")
    rig.write_text(text)
    assert main(["devices", str(rig), "--no-blink"]) == 1
    out = capsys.readouterr().out
    assert "NO  robot child2:" in out
    assert "ok  robot child1:" in out


def test_a_bad_rig_file_is_named_and_nothing_runs(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    rig.write_text((ROOT / "examples" / "paper_rig.toml").read_text().replace("p3at", "p3"))
    assert main(["run", str(SMOKE), "--rig", str(rig), "--out", str(tmp_path / "o")]) == 2
    out = capsys.readouterr().out
    assert f"{rig}: 1 problem(s) in the rig file" in out
    assert "robots[0].model" in out
    assert not (tmp_path / "o").exists()
    assert main(["devices", str(rig)]) == 2


@pytest.mark.parametrize(
    ("change", "key", "expected"),
    [
        (('name = "cam1"', 'name = "cam9"'), "cameras", "a [[cameras]] entry named 'cam1'"),
        (("led_bits = [0, 1, 2, 3]", "led_bits = [0, 1, 2]"), "robots[1].led_bits", "4 bits"),
    ],
    ids=["no-camera", "three-led-bits"],
)
@pytest.mark.parametrize("command", ["run", "check"])
def test_a_rig_that_does_not_fit_the_scenario_is_refused_before_anything_is_written(
    tmp_path, capsys, change, key, expected, command
):
    rig = tmp_path / "rig.toml"
    text = (ROOT / "examples" / "paper_rig.toml").read_text()
    assert change[0] in text
    rig.write_text(text.replace(change[0], change[1], 1))
    out = tmp_path / "o"
    out.mkdir()  # an empty folder, as a user makes one for the run
    args = [command, str(SMOKE), "--rig", str(rig), "--out", str(out)]
    if command == "check":  # the scenario's nominal camera, as a run would have written it
        (tmp_path / "cameras").mkdir()
        camera = load_scenario(SMOKE).cameras[0]
        save_camera(camera.tsai(), tmp_path / "cameras" / "cam1_visit1.json", name=camera.name)
        args += ["--cameras", str(tmp_path / "cameras")]
    assert main(args) == 2
    printed = capsys.readouterr().out
    assert f"{rig}: 1 problem(s) in the rig file" in printed
    assert key in printed
    assert expected in printed
    assert list(out.iterdir()) == []  # no log, no manifest: the next run is not refused


def test_twin_options_are_refused_with_a_rig(tmp_path, capsys):
    rig = ROOT / "examples" / "paper_rig.toml"
    code = main(["run", str(SMOKE), "--rig", str(rig), "--seed", "0", "--out", str(tmp_path)])
    assert code == 2
    assert "--seed apply to the twin, not to --rig" in capsys.readouterr().out


def test_a_device_that_cannot_be_opened_is_named(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    text = (ROOT / "examples" / "paper_rig.toml").read_text()
    rig.write_text(text.replace("/dev/ttyUSB0", str(tmp_path / "[/x]no-such-port")))
    code = main(["run", str(SMOKE), "--rig", str(rig), "--out", str(tmp_path / "o")])
    assert code == 2
    out = capsys.readouterr().out
    # The device, its port and its protocol.
    assert f"total_station on {tmp_path / '[/x]no-such-port'} (GeoCOM): cannot open" in out
    assert "DeviceLostError" not in out


def test_devices_shows_what_a_device_said_as_text(tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    text = (ROOT / "examples" / "paper_rig.toml").read_text()
    for k, port in enumerate(("/dev/ttyUSB0", "/dev/ttyS0", "socket://192.168.1.21:8101")):
        text = text.replace(port, str(tmp_path / f"no-port-{k}"))
    text = text.replace("socket://192.168.1.22:8101", str(tmp_path / "no-port-3"))
    for k, source in enumerate(("rtsp://192.168.1.31/stream1", "rtsp://192.168.1.32/stream1")):
        text = text.replace(source, str(tmp_path / f"[/x]cam{k}.avi"))
    rig.write_text(text.replace("http://192.168.1.33/video.mjpg", str(tmp_path / "cam2.avi")))
    assert main(["devices", str(rig), "--no-blink"]) == 1
    out = capsys.readouterr().out
    assert "[/x]cam0.avi" in out.replace("\n", "").replace(" ", "")


def test_emulate_refuses_a_bad_scenario(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 3\n")
    assert main(["emulate", str(bad), "--rig-out", str(tmp_path / "rig.toml")]) == 2
    assert not (tmp_path / "rig.toml").exists()


@pytest.mark.parametrize(
    ("rig_out", "expected"),
    [
        ("emu", "--rig-out emu: is a folder; expected the name of a file"),
        ("a_file/rig.toml", "--rig-out a_file/rig.toml: lies under the file a_file"),
        ("rig.toml", "--rig-out's truth file rig.truth.json: is a folder"),
    ],
)
def test_emulate_refuses_a_rig_out_it_cannot_write(
    rig_out, expected, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "emu").mkdir()
    (tmp_path / "a_file").write_text("the user's")
    (tmp_path / "rig.truth.json").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["emulate", str(SMOKE), "--rig-out", rig_out, "--duration", "1"]) == 2
    said = " ".join(capsys.readouterr().err.split())
    assert expected in said
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert not any((tmp_path / "emu").iterdir())


@pytest.mark.parametrize("value", ["1e9", "1001", "0.5", "0", "nan", "inf", "fast"])
def test_emulate_refuses_a_time_scale_out_of_range(value, tmp_path, capsys):
    rig = tmp_path / "rig.toml"
    with pytest.raises(SystemExit) as exit_:
        main(["emulate", str(SMOKE), "--rig-out", str(rig), "--time-scale", value])
    assert exit_.value.code == 2
    said = capsys.readouterr().err
    assert "argument --time-scale: expected" in said
    assert not rig.exists()
