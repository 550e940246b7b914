"""The ``twin`` commands that the documentation shows, and their check against the parser.

Two kinds of command are found in the Markdown: whole lines of fenced code blocks that start
with ``twin`` (a synopsis such as ``twin run SCENARIO [--seed N]`` continues on the indented
lines below it), and inline code spans in the prose that start with ``twin COMMAND``. A line
of a code block that names concrete values is parsed by the command line's own parser, as
the shell would hand it over; every command, a synopsis or an inline span (which hold
placeholders and fragments) as well, has its command, each ``--option`` (spelt whole) and
each value of an option with choices (``--fidelity render|geometric``) looked up in the
parser.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

_FENCE = re.compile(r"^(\s*)(```+|~~~+)\s*([\w+-]*)")
_SHELL_LANGUAGES = {"", "sh", "bash", "shell", "console"}
_INLINE = re.compile(r"(?<!`)`(twin [a-z][^`]*)`(?!`)")
_PLACEHOLDER = re.compile(r"^[A-Z][A-Z0-9_]*(\.[A-Za-z0-9.]+)?$")  # SCENARIO, N, RIG.toml


@dataclass(frozen=True)
class DocCommand:
    """One ``twin`` command as the documentation writes it.

    ``where`` is ``file:line``; ``text`` the command with its continuation lines joined;
    ``synopsis`` is true when it holds placeholders or alternatives (checked option by
    option) rather than values (parsed whole); ``inline`` for a span of the prose.
    """

    where: str
    text: str
    synopsis: bool
    inline: bool


def _is_synopsis(tokens: list[str]) -> bool:
    return any(
        "[" in t or "]" in t or "|" in t or "..." in t or _PLACEHOLDER.match(t) for t in tokens
    )


def _tokens(text: str) -> list[str]:
    """The words of a shell line, its comment and a trailing ``&`` left out."""
    tokens = shlex.split(text, comments=True)
    while tokens and tokens[-1] in {"&", "&&", ";"}:
        tokens.pop()
    return tokens


def commands_in(path: Path, root: Path) -> list[DocCommand]:
    """Every ``twin`` command of one Markdown file, in the order they appear."""
    lines = path.read_text(encoding="utf-8").splitlines()
    name = path.relative_to(root).as_posix()
    found: list[DocCommand] = []
    prose: list[tuple[int, str]] = []
    fence: str | None = None
    shell = False
    i = 0
    while i < len(lines):
        line = lines[i]
        m = _FENCE.match(line)
        if fence is None and m:
            fence, shell = m.group(2), m.group(3).lower() in _SHELL_LANGUAGES
            i += 1
            continue
        if fence is not None:
            if line.strip().startswith(fence):
                fence = None
            elif shell and line.lstrip().removeprefix("$ ").startswith("twin "):
                text, start = line.lstrip().removeprefix("$ "), i
                while text.rstrip().endswith("\\") or (
                    i + 1 < len(lines) and re.match(r"^\s+[\[-]", lines[i + 1])
                ):
                    text = text.rstrip().removesuffix("\\").rstrip() + " " + lines[i + 1].strip()
                    i += 1
                found.append(
                    DocCommand(f"{name}:{start + 1}", text, _is_synopsis(_tokens(text)), False)
                )
            i += 1
            continue
        prose.append((i, line))
        i += 1
    # Inline spans may run over a line break of the prose: search the prose joined.
    joined = "\n".join(text for _, text in prose)
    starts = [0]
    for _, text in prose:
        starts.append(starts[-1] + len(text) + 1)
    for m in _INLINE.finditer(joined):
        k = max(j for j, s in enumerate(starts) if s <= m.start())
        text = " ".join(m.group(1).split())
        found.append(DocCommand(f"{name}:{prose[k][0] + 1}", text, True, True))
    return found


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    raise AssertionError("the twin parser has no subcommands")


def problems(command: DocCommand, parser: argparse.ArgumentParser) -> list[str]:
    """What in ``command`` the parser does not have; empty when it runs as written."""
    tokens = _tokens(command.text)
    subs = _subcommands(parser)
    if len(tokens) < 2 or tokens[1] not in subs:
        name = tokens[1] if len(tokens) > 1 else ""
        return [f"no command 'twin {name}' (the commands: {', '.join(subs)})"]
    if not command.synopsis:
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err):
                parser.parse_args(tokens[1:])
        except SystemExit:
            return [err.getvalue().strip().splitlines()[-1]]
    # argparse takes a prefix of an option for the option: the pages must spell it whole.
    options = subs[tokens[1]]._option_string_actions
    found = []
    for at, token in enumerate(tokens[2:], start=2):
        for word in re.split(r"[\[\]|]", token):
            if not word.startswith("--"):
                continue
            option, _, value = word.partition("=")
            action = options.get(option)
            if action is None:
                found.append(f"twin {tokens[1]} has no option {option}")
                continue
            if action.choices is None or action.nargs == 0:
                continue
            # The value written after the option: one choice, or alternatives a|b|c.
            if not value and at + 1 < len(tokens):
                value = tokens[at + 1]
            if not value or value.startswith(("-", "[")) or _PLACEHOLDER.match(value):
                continue
            known = {str(c) for c in action.choices}
            for choice in value.strip("[]").split("|"):
                if choice not in known:
                    found.append(
                        f"twin {tokens[1]} {option}: no choice {choice!r} "
                        f"(the choices: {', '.join(map(str, action.choices))})"
                    )
    return found
