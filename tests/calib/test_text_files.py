"""Hand-written text files: UTF-8 with or without a byte-order mark, a byte that is not
UTF-8 named with its line, and YAML that repeats a key refused (TOML refuses it itself)."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.io.text import NotText, read_text, yaml_load


@settings(max_examples=60, deadline=None)
@given(text=st.text(max_size=200), bom=st.booleans())
def test_utf8_text_reads_back_with_or_without_a_byte_order_mark(tmp_path_factory, text, bom):
    path = tmp_path_factory.mktemp("t") / "f.toml"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode("utf-8"))
    # Only the first byte-order mark is the file's: one that the text begins with is text.
    expected = text if bom or not text.startswith("\ufeff") else text[1:]
    assert read_text(path) == expected


def test_a_byte_that_is_not_utf8_is_named_with_its_line(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'name = "a"\n# caf\xe9\n')
    with pytest.raises(NotText, match=r"line 2: byte b'\\xe9' is not UTF-8 text"):
        read_text(path)


def test_yaml_that_repeats_a_key_is_refused():
    with pytest.raises(yaml.YAMLError, match="found the key 'name' a second time"):
        yaml_load("name: a\nseed: 1\nname: b\n")
    with pytest.raises(yaml.YAMLError, match="'f' a second time"):
        yaml_load("cameras:\n  - {f: 1, f: 2}\n")


def test_yaml_without_repeats_reads_as_the_safe_loader_reads_it():
    text = "a: 1\nb: [1, 2, {c: x}]\nd: {e: null, f: 2.5}\nbase: &b {g: 1}\nh:\n  <<: *b\n  i: 2\n"
    assert yaml_load(text) == yaml.safe_load(text)
