"""Reading and validating scenario files (TOML, or YAML by extension)."""

from __future__ import annotations

import json
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, TypeVar

import annotated_types
import yaml
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from calib.io.text import NotText, read_text, yaml_load
from twin.scenario.cross_checks import check_scenario
from twin.scenario.errors import ScenarioError, ScenarioIssue
from twin.scenario.map_space import with_map_boxes
from twin.scenario.schema import Scenario

# What a user should have written, by pydantic error type.
_EXPECTED = {
    "float_type": "a number",
    "finite_number": "a finite number",
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
    "string_pattern_mismatch": "a name of letters, digits and _ that starts with a letter",
}

# Errors of a number out of its range (NaN and infinity included): the expected value is
# the range, read from the schema.
_RANGE_ERRORS = (
    "greater_than",
    "greater_than_equal",
    "less_than",
    "less_than_equal",
    "finite_number",
)

# What is wrong with a number out of its range, in place of pydantic's "Input should be...".
_RANGE_PROBLEMS = {
    "greater_than": "too small",
    "greater_than_equal": "too small",
    "less_than": "too large",
    "less_than_equal": "too large",
    "finite_number": "not a finite number",
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
    return scenario_from_dict(read_mapping(path), file=path)


def read_mapping(path: Path, error: type[ScenarioError] = ScenarioError) -> Mapping[str, Any]:
    """The table a TOML file (YAML for ``.yaml``/``.yml``) holds.

    Raises:
        ``error`` (a :class:`ScenarioError`): the file cannot be read, does not parse, or
            does not hold a table.
    """
    try:
        text = read_text(path)
    except OSError as exc:
        raise error(path, [ScenarioIssue("<file>", str(exc), None, "a readable file")]) from None
    except NotText as exc:
        raise error(path, [ScenarioIssue("<file>", str(exc), None, "UTF-8 text")]) from None
    try:
        yaml_file = path.suffix.lower() in (".yaml", ".yml")
        raw = yaml_load(text) if yaml_file else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, yaml.YAMLError) as exc:
        raise error(
            path, [ScenarioIssue("<syntax>", str(exc), None, "valid TOML or YAML")]
        ) from None
    if not isinstance(raw, Mapping):
        raise error(path, [ScenarioIssue("<top>", "not a table", None, "key = value")])
    return raw


def scenario_from_dict(raw: Mapping[str, Any], file: str | Path = "<dict>") -> Scenario:
    """Validate a parsed scenario mapping (see :func:`load_scenario`); a space that
    references its map (``[space.map]``) gets the map's boxes, the map read relative to
    ``file``'s folder (:mod:`twin.scenario.map_space`)."""
    data = dict(raw)
    if "source" in data:
        raise ScenarioError(
            file, [ScenarioIssue("source", "reserved key", data["source"], "no such key")]
        )
    data["source"] = str(file)
    sc = with_map_boxes(validate_model(Scenario, data, file), file)
    issues = check_scenario(sc)
    if issues:
        raise ScenarioError(file, issues)
    return sc


M = TypeVar("M", bound=BaseModel)


def validate_model(
    model: type[M],
    data: Mapping[str, Any],
    file: str | Path = "<dict>",
    error: type[ScenarioError] = ScenarioError,
) -> M:
    """``data`` validated as ``model`` the way scenario files are: JSON mode with strict
    types (lists become tuples, but "3" never becomes 3.0).

    Raises:
        ``error`` (a :class:`ScenarioError`): naming ``file``, each key, its value and what
            was expected.
    """
    try:
        return model.model_validate_json(json.dumps(data, default=str), strict=True)
    except ValidationError as exc:
        raise error(file, validation_issues(exc, data, model)) from None


def validation_issues(
    exc: ValidationError, data: Mapping[str, Any], root: type[BaseModel]
) -> list[ScenarioIssue]:
    """Each problem pydantic found validating ``data`` as ``root``, as a
    :class:`ScenarioIssue` that names the key, the value and what was expected."""
    errors = exc.errors()
    locs = [tuple(e["loc"]) for e in errors]
    # A list whose items failed also reports "too short after validation": drop that.
    errors = [
        e
        for e in errors
        if not (
            e["type"] == "too_short"
            and any(
                len(loc) > len(e["loc"]) and loc[: len(e["loc"])] == tuple(e["loc"]) for loc in locs
            )
        )
    ]
    return [_issue(err, data, root) for err in errors]


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


def _unwrap(annotation: Any) -> tuple[Any, list[Any]]:
    """``annotation`` without its ``Annotated`` wrappers and its ``| None``, and the
    constraints (``annotated_types`` metadata) those wrappers carried."""
    constraints: list[Any] = []
    while True:
        origin = typing.get_origin(annotation)
        args = typing.get_args(annotation)
        if origin is Annotated:
            annotation = args[0]
            for extra in args[1:]:
                constraints += extra.metadata if isinstance(extra, FieldInfo) else [extra]
        elif origin in (typing.Union, types.UnionType) and len(args) == 2 and type(None) in args:
            annotation = next(a for a in args if a is not type(None))
        else:
            return annotation, constraints


def _type_at(loc: tuple[Any, ...], root: type[BaseModel]) -> tuple[Any, list[Any]]:
    """The type of the value at ``loc`` of a ``root`` and the constraints on it; (None, [])
    where ``loc`` leads nowhere known."""
    annotation: Any = root
    constraints: list[Any] = []
    for part in loc:
        if isinstance(part, int):
            args = typing.get_args(annotation) if typing.get_origin(annotation) is tuple else ()
            if len(args) == 2 and args[1] is Ellipsis:
                annotation, constraints = _unwrap(args[0])
            elif part < len(args):
                annotation, constraints = _unwrap(args[part])
            else:
                return None, []
        else:
            field = annotation.model_fields.get(str(part)) if _is_model(annotation) else None
            if field is None:
                return None, []
            annotation, constraints = _unwrap(field.annotation)
            constraints = [*field.metadata, *constraints]
    return annotation, constraints


def _is_model(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, BaseModel)


def _number(x: float) -> str:
    """``x`` as a range's bound: 5000 rather than 5000.0, 1e-05 as written by repr."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e16:
        return str(int(x))
    return repr(x)


def _range(annotation: Any, constraints: list[Any]) -> str | None:
    """The accepted range of a number, if it has one: "a number in [lo, hi]" (an open end
    in round brackets) where it has both ends, else in words ("a number above 0")."""
    lo = hi = None
    for c in constraints:
        if isinstance(c, annotated_types.Ge):
            lo = ("ge", c.ge)
        elif isinstance(c, annotated_types.Gt):
            lo = ("gt", c.gt)
        elif isinstance(c, annotated_types.Le):
            hi = ("le", c.le)
        elif isinstance(c, annotated_types.Lt):
            hi = ("lt", c.lt)
    what = "an integer" if annotation is int else "a number"
    if lo is not None and hi is not None:
        left = "[" if lo[0] == "ge" else "("
        right = "]" if hi[0] == "le" else ")"
        return f"{what} in {left}{_number(lo[1])}, {_number(hi[1])}{right}"
    bound = lo or hi
    return None if bound is None else _bound(what, *bound)


# A one-sided range in words, by pydantic's name of the bound.
_BOUND_WORDS = {"gt": "above {}", "ge": "of at least {}", "lt": "below {}", "le": "of at most {}"}


def _bound(what: str, kind: str, value: Any) -> str:
    """``what`` ("a number") bounded on one side, in words: "a number above 0"."""
    return f"{what} {_BOUND_WORDS[kind].format(_number(value))}"


def _range_of_error(err: Mapping[str, Any]) -> str | None:
    """The range a range error names (its context, where the schema is not at hand), in
    words; None if it names none."""
    ctx = err.get("ctx", {})
    for kind in _BOUND_WORDS:
        if kind in ctx:
            what = "an integer" if isinstance(ctx[kind], int) else "a number"
            return _bound(what, kind, ctx[kind])
    return None


def _count(constraints: list[Any]) -> str | None:
    """The accepted number of items of a list, if it is limited."""
    least = next((c.min_length for c in constraints if isinstance(c, annotated_types.MinLen)), 0)
    most = next((c.max_length for c in constraints if isinstance(c, annotated_types.MaxLen)), None)
    if most is None:
        return f"at least {least} items" if least else None
    return f"{least} to {most} items" if least else f"at most {most} items"


def _expected(err: Mapping[str, Any], loc: tuple[Any, ...], root: type[BaseModel]) -> str:
    """What the user should have written where ``err`` happened."""
    typ = err["type"]
    if "expected" in err.get("ctx", {}):
        return str(err["ctx"]["expected"])
    if typ in _RANGE_ERRORS:
        return (
            _range(*_type_at(loc, root))
            or _range_of_error(err)
            or _EXPECTED.get(typ)
            or "a number in the documented range"
        )
    if typ in ("too_short", "too_long"):
        return _count(_type_at(loc, root)[1]) or err["msg"]
    if typ == "value_error":
        return "a consistent value (see the schema's documentation)"
    return _EXPECTED.get(typ) or err["msg"]


def _issue(err: Mapping[str, Any], data: Mapping[str, Any], root: type[BaseModel]) -> ScenarioIssue:
    loc = tuple(err["loc"])
    typ = err["type"]
    if typ == "extra_forbidden":
        model = _type_at(loc[:-1], root)[0]
        keys = ", ".join(model.model_fields) if _is_model(model) else "a documented key"
        return ScenarioIssue(_key(loc), "unknown key", None, f"one of: {keys}")
    value = None if typ == "missing" else _value_at(data, loc)
    if typ == "missing":
        problem = "missing"
    else:
        problem = _RANGE_PROBLEMS.get(typ) or err["msg"].removeprefix("Value error, ")
        if typ in _RANGE_PROBLEMS and isinstance(value, float) and not math.isfinite(value):
            problem = _RANGE_PROBLEMS["finite_number"]  # NaN is neither small nor large
    return ScenarioIssue(_key(loc), problem, value, _expected(err, loc, root))
