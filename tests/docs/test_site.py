"""The documentation site builds with ``--strict``: a broken link, a missing image or page,
a page left out of the nav or a wrong anchor fails ``make test``; the README, which GitHub
shows rather than MkDocs, has its links and its figure checked here too."""

from __future__ import annotations

import logging
import re
import shutil
from pathlib import Path

import pytest
from mkdocs.commands.build import build
from mkdocs.config import load_config
from mkdocs.exceptions import Abort

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 250


def _build(config: Path, site: Path) -> None:
    """Build the site of ``config`` into ``site`` as ``make docs`` does (strict)."""
    build(load_config(config_file=str(config), site_dir=str(site), strict=True))


def test_the_site_builds_strict_with_every_page(tmp_path):
    _build(ROOT / "mkdocs.yml", tmp_path / "site")
    pages = sorted(p.stem for p in (ROOT / "docs").glob("*.md"))
    assert len(pages) >= 15
    for page in pages:
        built = "index.html" if page == "index" else f"{page}/index.html"
        assert (tmp_path / "site" / built).is_file(), page
    assert (tmp_path / "site" / "img" / "paper_hall_top_view.png").is_file()


@pytest.mark.parametrize(
    ("page", "change", "culprit"),
    [
        ("run.md", "See [the missing page](no_such_page.md).", "no_such_page.md"),
        ("reports.md", "![a figure](img/no_such_figure.png)", "no_such_figure.png"),
        ("run.md", "See [a section](check.md#no-such-section).", "no-such-section"),
        ("unlisted.md", "# A page the nav does not list", "unlisted.md"),
    ],
)
def test_a_broken_site_fails_the_build(tmp_path, caplog, page, change, culprit):
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    with (tmp_path / "docs" / page).open("a", encoding="utf-8") as f:
        f.write(f"\n{change}\n")
    with caplog.at_level(logging.WARNING, logger="mkdocs"), pytest.raises(Abort):
        _build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert culprit in caplog.text


def _readme() -> str:
    return (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_readme_links_and_figure_resolve():
    targets = re.findall(r"\]\(([^)\s]+)\)", _readme())
    local = [t.split("#")[0] for t in targets if not re.match(r"[a-z]+:", t) and t[0] != "#"]
    assert "docs/img/paper_hall_top_view.png" in local
    assert "docs/index.md" in local
    missing = [t for t in local if not (ROOT / t).exists()]
    assert missing == [], f"README.md links to files that do not exist: {missing}"


def test_the_readme_stays_a_front_door():
    """The two commands open it, and the reference lives in docs/, not in the README."""
    text = _readme()
    first = text.splitlines()[:5]
    assert first[0] == "# camnet-twin"
    assert first[2] == "```sh"
    assert first[3].startswith("make run ")
    assert first[4].startswith("make test ")
    lines = len(text.splitlines())
    assert lines <= README_MAX_LINES, (
        f"README.md has {lines} lines; keep it a ten-minute tour (at most "
        f"{README_MAX_LINES}) and put reference text in a page of docs/"
    )


def test_the_pages_the_code_names_exist():
    """A help text or docstring that sends the reader to a page names one that exists."""
    named = {
        (path.relative_to(ROOT).as_posix(), page)
        for package in ("twin", "calib")
        for path in (ROOT / package).rglob("*.py")
        for page in re.findall(r"\bdocs/[\w-]+\.md\b", path.read_text(encoding="utf-8"))
    }
    assert ("twin/cli/montecarlo.py", "docs/montecarlo.md") in named
    missing = sorted((where, page) for where, page in named if not (ROOT / page).is_file())
    assert missing == [], f"pages named in the code that docs/ lacks: {missing}"
