"""Every ``twin`` command the documentation shows runs as written: its command, options and
choices are the command line's (a renamed option or choice fails here)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.docs.doc_commands import DocCommand, commands_in, problems
from twin.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
PAGES = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
COMMANDS = [c for page in PAGES for c in commands_in(page, ROOT)]


@pytest.fixture(scope="module")
def parser():
    return build_parser()


def test_the_docs_show_commands_of_every_kind():
    """The search finds whole lines, synopses and inline spans (an empty search passes all)."""
    kinds = {(c.synopsis, c.inline) for c in COMMANDS}
    assert kinds == {(False, False), (True, False), (True, True)}
    shown = {c.text.split()[1] for c in COMMANDS}
    assert shown >= {"calibrate", "scene", "render", "detect", "run", "check", "montecarlo"}
    assert shown >= {"strategies", "site", "emulate", "devices", "replay"}


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c.where)
def test_documented_command_runs_as_written(command: DocCommand, parser):
    assert problems(command, parser) == [], f"{command.where}: {command.text}"


@pytest.mark.parametrize(
    ("text", "synopsis", "culprit"),
    [
        ("twin run scenarios/smoke.toml --no-such-option", False, "--no-such-option"),
        ("twin run scenarios/smoke.toml --fidelity batch", False, "'batch'"),
        ("twin runs scenarios/smoke.toml", False, "twin runs"),
        ("twin run scenarios/smoke.toml --over", False, "--over"),
        ("twin run SCENARIO [--seed N] [--no-such-option]", True, "--no-such-option"),
        ("twin run SCENARIO [--strategy planned|greedy]", True, "'greedy'"),
        ("twin replay LOG --adjust shared|per_camera", True, "'per_camera'"),
        ("twin montecarlo SCENARIO [--resume | --restart]", True, "--restart"),
    ],
)
def test_a_command_the_parser_lacks_is_named(text, synopsis, culprit, parser):
    found = problems(DocCommand("x.md:1", text, synopsis, synopsis), parser)
    assert found
    assert culprit in " ".join(found)


def test_code_blocks_are_read_as_the_shell_reads_them(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "Run `twin run --seed\n3` in prose.\n\n"
        "```sh\n"
        "twin run SCENARIO [--seed N]\n"
        "         [--overwrite]\n"
        "$ twin scene scenarios/smoke.toml \\\n"
        "    --export out/x.xml  # note\n"
        "twin emulate scenarios/smoke.toml --rig-out r.toml &\n"
        "```\n\n"
        "```python\ntwin run not a shell line\n```\n",
        encoding="utf-8",
    )
    found = commands_in(page, tmp_path)
    assert [(c.where, c.text, c.synopsis, c.inline) for c in found] == [
        ("page.md:5", "twin run SCENARIO [--seed N] [--overwrite]", True, False),
        ("page.md:7", "twin scene scenarios/smoke.toml --export out/x.xml  # note", False, False),
        ("page.md:9", "twin emulate scenarios/smoke.toml --rig-out r.toml &", False, False),
        ("page.md:1", "twin run --seed 3", True, True),
    ]
