"""Reading and validating scenario files (TOML, or YAML by extension)."""

from __future__ import annotations

import json
import tomllib
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from twin.scenario.cross_checks import check_scenario
from twin.scenario.errors import ScenarioError, ScenarioIssue
from twin.scenario.schema import Scenario

# What a user should have written, by pydantic error type.
_EXPECTED = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "string_type": "a string",
    "bool_type": "true or false",
    "tuple_type": "a list",
    "list_type": "a list",
    "dict_type": "a table (section)",
    "model_type": "a table (section)",
    "model_attributes_type": "a table (section)",
    "missing": "this key to be present",
    "literal_error": None,
    "greater_than": None,
    "greater_than_equal": None,
    "less_than": None,
    "less_than_equal": None,
    "too_short": None,
    "too_long": None,
    "string_pattern_mismatch": "a name of letters, digits and _ that starts with a letter",
}


def load_scenario(path: str | Path) -> Scenario:
    """Read, validate and cross-check a scenario file.

    Args:
        path: a ``.toml`` file (``.yaml``/``.yml`` are read as YAML).

    Returns:
        The frozen scenario, with ``source`` set to the path.

    Raises:
        ScenarioError: the file cannot be read or parsed, or any key is unknown, mistyped,
            out of range or inconsistent with the rest; the message names the file, each
            key, its value and what was expected.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        issue = ScenarioIssue("<file>", str(exc), None, "a readable file")
        raise ScenarioError(path, [issue]) from None
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            raw = yaml.safe_load(text)
        else:
            raw = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, yaml.YAMLError) as exc:
        raise ScenarioError(
            path, [ScenarioIssue("<syntax>", str(exc), None, "valid TOML or YAML")]
        ) from None
    if not isinstance(raw, Mapping):
        raise ScenarioError(path, [ScenarioIssue("<top>", "not a table", None, "key = value")])
    return scenario_from_dict(raw, file=path)


def scenario_from_dict(raw: Mapping[str, Any], file: str | Path = "<dict>") -> Scenario:
    """Validate a parsed scenario mapping (see :func:`load_scenario`)."""
    data = dict(raw)
    if "source" in data:
        raise ScenarioError(
            file, [ScenarioIssue("source", "reserved key", data["source"], "no such key")]
        )
    data["source"] = str(file)
    try:
        # JSON mode with strict types: lists become tuples, but "3" never becomes 3.0.
        sc = Scenario.model_validate_json(json.dumps(data, default=str), strict=True)
    except ValidationError as exc:
        errors = exc.errors()
        locs = [tuple(e["loc"]) for e in errors]
        # A list whose items failed also reports "too short after validation": drop that.
        errors = [
            e
            for e in errors
            if not (
                e["type"] == "too_short"
                and any(
                    len(loc) > len(e["loc"]) and loc[: len(e["loc"])] == tuple(e["loc"])
                    for loc in locs
                )
            )
        ]
        raise ScenarioError(file, [_issue(err, data) for err in errors]) from None
    issues = check_scenario(sc)
    if issues:
        raise ScenarioError(file, issues)
    return sc


def _key(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<top>"


def _value_at(data: Any, loc: tuple[Any, ...]) -> Any:
    for part in loc:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _model_at(loc: tuple[Any, ...]) -> type[BaseModel] | None:
    """The pydantic model of the table at ``loc`` (to list its keys), if it is one."""
    model: Any = Scenario
    for part in loc:
        if isinstance(part, int):
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return None
        field = model.model_fields.get(str(part))
        if field is None:
            return None
        model = _inner_model(field.annotation)
    return model if isinstance(model, type) and issubclass(model, BaseModel) else None


def _inner_model(annotation: Any) -> Any:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _inner_model(arg)
        if found is not None:
            return found
    return None


def _issue(err: Mapping[str, Any], data: Mapping[str, Any]) -> ScenarioIssue:
    loc = tuple(err["loc"])
    typ = err["type"]
    if typ == "extra_forbidden":
        model = _model_at(loc[:-1])
        keys = ", ".join(model.model_fields) if model else "a documented key"
        return ScenarioIssue(_key(loc), "unknown key", None, f"one of: {keys}")
    value = None if typ == "missing" else _value_at(data, loc)
    expected = _EXPECTED.get(typ) or err["msg"]
    problem = "missing" if typ == "missing" else err["msg"]
    if typ == "value_error":
        problem = err["msg"].removeprefix("Value error, ")
        expected = "a consistent value (see the schema's documentation)"
    return ScenarioIssue(_key(loc), problem, value, expected)
