"""The rig file: the example loads and fits the paper's hall; every bad value is named."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from twin.drivers.rig_file import (
    RigFileError,
    check_fits,
    load_rig_file,
    rig_file_from_dict,
    write_rig_file,
)
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "examples" / "paper_rig.toml"


def _raw() -> dict:
    return tomllib.loads(EXAMPLE.read_text())


def test_the_example_rig_loads_and_fits_the_paper_hall() -> None:
    rig = load_rig_file(EXAMPLE)
    assert rig.source == str(EXAMPLE)
    assert [r.name for r in rig.robots] == ["parent", "child1", "child2"]
    assert rig.robot("child2").led_bits == (0, 1, 2, 3)
    assert rig.robot("parent").model == "p3at"
    assert [c.name for c in rig.cameras] == ["cam1", "cam2", "cam3"]
    assert rig.total_station.driver == "geocom"
    check_fits(rig, load_scenario(ROOT / "scenarios" / "paper_hall.toml"))


@pytest.mark.parametrize(
    ("change", "key", "expected"),
    [
        (lambda r: r.update(time_scale=0.0), "time_scale", "a number in (0, 1000]"),
        (lambda r: r["total_station"].update(driver="topcon"), "total_station.driver", "'geocom'"),
        (lambda r: r["total_station"].update(baud=-9600), "total_station.baud", "an integer in"),
        (lambda r: r["total_station"].pop("port"), "total_station.port", "present"),
        (lambda r: r["robots"][0].update(model="p2dx"), "robots[0].model", "'p3dx' or 'p3at'"),
        (lambda r: r["robots"][1].update(led_bits=[0, 1, 2, 9]), "robots[1].led_bits[3]", "[0, 7]"),
        (lambda r: r["robots"][1].update(led_bits=[0, 1, 1, 2]), "robots[1].led_bits", "one bit"),
        (lambda r: r["robots"][2].update(name="child1"), "robots[2].name", "unique names"),
        (lambda r: r["robots"][0].update(wheels=4), "robots[0].wheels", "one of: name, model"),
        (
            lambda r: r["cameras"][0].update(settle_frames=-1),
            "cameras[0].settle_frames",
            "[0, 100]",
        ),
        (lambda r: r["cameras"][0].update(timeout_s="5"), "cameras[0].timeout_s", "a number"),
        (lambda r: r.update(robots=r["robots"][:2]), "robots", "at least 3 items"),
        (
            lambda r: r["cameras"][0].update(driver="genicam", source=3),
            "cameras[0].source",
            ".cti",
        ),
    ],
)
def test_a_bad_value_is_named_with_its_file_key_and_what_was_expected(
    change, key: str, expected: str
) -> None:
    raw = _raw()
    change(raw)
    with pytest.raises(RigFileError) as caught:
        rig_file_from_dict(raw, file="my_rig.toml")
    text = str(caught.value)
    assert text.startswith("my_rig.toml:")
    assert "rig file" in text
    line = next(line for line in text.splitlines() if line.strip().startswith(f"- {key}:"))
    assert expected in line


def test_unreadable_and_unparsable_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(RigFileError, match=r"missing\.toml"):
        load_rig_file(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("time_scale = = 2\n")
    with pytest.raises(RigFileError, match=r"bad.toml.*\n.*<syntax>"):
        load_rig_file(bad)


def test_a_rig_without_a_device_the_scenario_needs_is_refused() -> None:
    raw = _raw()
    raw["cameras"] = raw["cameras"][:2]
    raw["robots"][1]["led_bits"] = [0, 1, 2]
    rig = rig_file_from_dict(raw, file="short.toml")
    with pytest.raises(RigFileError) as caught:
        check_fits(rig, load_scenario(ROOT / "scenarios" / "paper_hall.toml"))
    text = str(caught.value)
    assert "no device for camera 'cam3'" in text
    assert "robots[1].led_bits" in text
    assert "4 bits (the marker has 4 LEDs)" in text


@pytest.mark.parametrize("suffix", [".toml", ".yaml"])
def test_a_written_rig_file_reads_back_as_written(suffix: str, tmp_path: Path) -> None:
    path = tmp_path / f"rig{suffix}"
    written = write_rig_file(path, _raw())
    assert load_rig_file(path).model_dump(exclude={"source"}) == written.model_dump(
        exclude={"source"}
    )
    assert written == rig_file_from_dict(_raw(), file=path)


def test_a_rig_file_the_reader_refuses_is_named_by_its_own_name(tmp_path: Path) -> None:
    raw = _raw()
    raw["robots"][0]["timeout_s"] = 2.5e9
    with pytest.raises(RigFileError) as caught:
        write_rig_file(tmp_path / ".tmp-rig.toml", raw, name="rig.toml")
    text = str(caught.value)
    assert text.startswith("rig.toml:")
    assert "robots[0].timeout_s" in text
