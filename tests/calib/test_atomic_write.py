"""Camera files are written whole or not at all."""

from __future__ import annotations

from pathlib import Path

import pytest

import calib.io.camera_files as camera_files
from calib.io import load_camera, save_camera
from calib.io.atomic import atomic_file
from calib.synthetic import paper_camera


@pytest.mark.parametrize(
    ("name", "writer"),
    [("cam.yaml", "_write_opencv_yaml"), ("cam.camera_info.yaml", "_write_ros_yaml")],
)
def test_a_failed_write_leaves_the_old_file_and_nothing_else(
    tmp_path, monkeypatch, name, writer
) -> None:
    path = tmp_path / name
    save_camera(paper_camera(1), path)
    before = path.read_bytes()

    def write_half_then_fail(target: Path, *args: object) -> None:
        target.write_text("image_width: 3")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(camera_files, writer, write_half_then_fail)
    with pytest.raises(OSError, match="No space left"):
        save_camera(paper_camera(2), path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == [name]
    assert load_camera(path).image_size == (320, 240)


def test_atomic_file_renames_only_a_complete_file(tmp_path) -> None:
    path = tmp_path / "out.txt"

    def write_partial() -> None:
        with atomic_file(path) as tmp:
            tmp.write_text("partial")
            raise RuntimeError("the writer failed")

    with pytest.raises(RuntimeError, match="the writer failed"):
        write_partial()
    assert list(tmp_path.iterdir()) == []
    with atomic_file(path) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.endswith("-out.txt")
        tmp.write_text("complete")
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]
    assert path.read_text() == "complete"


def test_a_camera_under_a_regular_file_is_an_os_error(tmp_path) -> None:
    (tmp_path / "file").write_text("")
    with pytest.raises(FileExistsError, match="File exists"):
        save_camera(paper_camera(1), tmp_path / "file" / "cam.json")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
