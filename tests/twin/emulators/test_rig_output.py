"""The rig file ``twin emulate`` writes: one the rig reader accepts at every time scale the
emulation takes, written with its truth file or not at all."""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from types import SimpleNamespace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.drivers.rig_file import MAX_SECONDS, MAX_TIME_SCALE, load_rig_file, rig_file_from_dict
from twin.emulators.emulation import (
    MAX_TIME_SCALE as MAX_EMULATED,
)
from twin.emulators.emulation import (
    MIN_TIME_SCALE,
    Emulation,
    check_time_scale,
)
from twin.outputs import OutputError
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
SMOKE = load_scenario(ROOT / "scenarios" / "smoke.toml")


def emulation(time_scale: float) -> Emulation:
    """An emulation of the smoke room whose devices are only addresses (nothing served):
    enough to write its rig file."""
    return Emulation(
        scenario=SMOKE,
        fidelity="geometric",
        time_scale=time_scale,
        total_station=SimpleNamespace(address="/dev/pts/99"),
        robots={r.name: SimpleNamespace(address="socket://127.0.0.1:9") for r in SMOKE.robots.all},
        cameras={c.name: SimpleNamespace(url="http://127.0.0.1:9/") for c in SMOKE.cameras},
        truth={"cam1": {"f": 400.0}},
        sim=None,
        lock=threading.RLock(),
    )


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=MIN_TIME_SCALE, max_value=MAX_EMULATED))
def test_every_time_scale_taken_gives_a_rig_file_the_reader_accepts(time_scale):
    assert check_time_scale(time_scale) == time_scale
    rig = rig_file_from_dict(emulation(time_scale).rig_file())
    assert rig.time_scale == time_scale
    # Every timeout the drivers keep is at least the emulators' wall margins, in rig time.
    assert min(r.timeout_s for r in rig.robots) >= 2.5 * time_scale * (1 - 1e-12)
    assert min(c.timeout_s for c in rig.cameras) == pytest.approx(5.0 * time_scale)


def test_the_largest_time_scale_is_the_reader_s():
    assert MAX_EMULATED == MAX_TIME_SCALE
    assert 5.0 * MAX_EMULATED <= MAX_SECONDS  # the cameras' timeout
    rig_file_from_dict(emulation(MAX_EMULATED).rig_file())


@pytest.mark.parametrize(
    "value",
    [
        0.0,
        -1.0,
        math.nextafter(MIN_TIME_SCALE, 0),
        math.nextafter(MAX_EMULATED, math.inf),
        1e9,
        math.nan,
        math.inf,
    ],
)
def test_a_time_scale_out_of_range_is_refused_with_the_range(value):
    with pytest.raises(ValueError, match=r"time scale: expected 1 to 1000 rig seconds per wall"):
        check_time_scale(value)


@pytest.mark.parametrize("name", ["rig.toml", "rig.yaml"])
def test_the_rig_file_reads_back_with_its_truth(name, tmp_path):
    path = emulation(30.0).write_rig_file(tmp_path / "emu" / name, "--rig-out")
    rig = load_rig_file(path)
    assert rig.time_scale == 30.0
    assert [r.name for r in rig.robots] == ["parent", "child1", "child2"]
    assert rig.emulator.truth == Path(name).stem + ".truth.json"
    truth = json.loads((path.parent / rig.emulator.truth).read_text())
    assert truth == {"cameras": {"cam1": {"f": 400.0}}}
    assert sorted(p.name for p in path.parent.iterdir()) == sorted([name, rig.emulator.truth])


def test_a_rig_file_the_reader_refuses_is_not_written(tmp_path):
    bad = emulation(1e9)  # as an unchecked time scale made it
    with pytest.raises(OutputError) as refused:
        bad.write_rig_file(tmp_path / "emu" / "rig.toml", "--rig-out")
    said = str(refused.value)
    assert said.startswith(f"--rig-out {tmp_path / 'emu' / 'rig.toml'}: ")
    assert "time_scale" in said
    assert "cameras[0].timeout_s" in said
    assert not (tmp_path / "emu").exists()  # the folder made for it is removed too
