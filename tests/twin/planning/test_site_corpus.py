"""The real maps the sites benchmark runs on: each reads as a map, each is listed with its
source and licence, and all of them stay small."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.planning.maps import load_map

SITES = Path(__file__).resolve().parents[3] / "benchmarks" / "sites"
FOLDERS = sorted(p for p in (SITES / "maps").iterdir() if p.is_dir())


def test_the_corpus_holds_ten_maps_or_more_in_20_mb():
    assert len(FOLDERS) >= 10
    size = sum(f.stat().st_size for f in (SITES / "maps").rglob("*") if f.is_file())
    assert size <= 20e6


@pytest.mark.parametrize("folder", FOLDERS, ids=[p.name for p in FOLDERS])
def test_each_map_reads_and_names_its_source_and_licence(folder):
    floor = load_map(folder / "map.yaml")
    assert floor.free.area > 50.0  # a building's floor, m^2
    row = [ln for ln in (SITES / "SOURCES.md").read_text().splitlines() if f"`{folder.name}`" in ln]
    assert len(row) == 1
    assert "https://github.com/" in row[0]
    assert any(word in row[0] for word in ("MIT", "Apache-2.0", "BSD"))
