"""Text files people write by hand (scenarios, rigs, maps, camera lists): read as UTF-8,
with or without the byte-order mark some editors put first (Windows Notepad does), and
YAML whose mappings may not repeat a key (TOML refuses a repeated key; YAML's loaders keep
the last one silently, and a scenario would then run with a value its author did not
mean).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

__all__ = ["NotText", "read_text", "yaml_load"]


class NotText(ValueError):
    """The file is not UTF-8 text: the message says where it stops being text."""


def read_text(path: str | Path) -> str:
    """The file's text (UTF-8; a leading byte-order mark is dropped).

    Raises:
        NotText: a byte that is not UTF-8, named with its line.
        OSError: the file cannot be read.
    """
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        byte = data[exc.start : exc.start + 1]
        raise NotText(f"line {line}: byte {byte!r} is not UTF-8 text") from None


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a key that a mapping repeats."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue  # "<<: *anchor": the merged keys may be set again here
            key = self.construct_object(key_node, deep=deep)
            try:
                repeated = key in seen
            except TypeError:  # an unhashable key: the base class reports it
                break
            if repeated:
                raise yaml.constructor.ConstructorError(
                    "while constructing a mapping",
                    node.start_mark,
                    f"found the key {key!r} a second time",
                    key_node.start_mark,
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def yaml_load(text: str) -> Any:
    """A YAML document, as :func:`yaml.safe_load` reads it, but a mapping that repeats a
    key is refused.

    Raises:
        yaml.YAMLError: the text does not parse, or a mapping repeats a key.
    """
    return yaml.load(text, Loader=_UniqueKeyLoader)
