"""Records to plain JSON values and back.

:func:`encode` turns a record (a frozen dataclass, or a mapping of plain values) into a dict
that :func:`json.dumps` writes with ``allow_nan=False``:

- dataclasses, recursively, become dicts of their fields plus ``"_type"``, the class name;
- numpy arrays become (nested) lists, numpy scalars Python scalars;
- NaN and +/-inf become ``None`` (strict JSON has no such numbers);
- enums become their value, tuples lists, mappings dicts with ``str`` keys.

:func:`decode` rebuilds the records of :data:`RECORD_TYPES` from such a dict, guided by the
field annotations: a ``None`` in a float field or array comes back as NaN (so +/-inf comes
back as NaN too), lists come back as tuples or arrays where the field asks for one. Units
are those of the records: nothing is converted.
"""

from __future__ import annotations

import enum
import functools
import math
import types
from collections.abc import Mapping
from dataclasses import MISSING, fields, is_dataclass
from typing import Any, Union, get_args, get_origin, get_type_hints

import numpy as np
from numpy.typing import NDArray

from twin.hal.readings import (
    DriveResult,
    Event,
    LedObservation,
    LedSwitch,
    OdometryReading,
    TiltReading,
    TotalStationMeasurement,
)

__all__ = ["RECORD_TYPES", "TYPE_KEY", "decode", "encode"]

TYPE_KEY = "_type"
"""The key under which an encoded dataclass names its class."""

RECORD_TYPES: Mapping[str, type] = {
    cls.__name__: cls
    for cls in (
        OdometryReading,
        DriveResult,
        LedSwitch,
        LedObservation,
        Event,
        TotalStationMeasurement,
        TiltReading,
    )
}
"""The record classes :func:`decode` rebuilds, by class name. (Camera images are not
recorded: :class:`~twin.hal.readings.CameraImage` encodes, but decodes as a plain dict.)"""


# --- encoding ------------------------------------------------------------------------------


def encode(record: object) -> dict[str, Any]:
    """A dataclass record, or a mapping of plain values, as a dict of JSON values.

    Raises TypeError, naming the field and the type, for a value with no JSON form.
    """
    if is_dataclass(record) and not isinstance(record, type):
        return _encode_dataclass(record, type(record).__name__)
    if isinstance(record, Mapping):
        return _encode_mapping(record, "record")
    raise TypeError(
        f"cannot encode a {type(record).__name__} as a record: expected a dataclass or a mapping"
    )


def _encode_value(value: Any, where: str) -> Any:
    """One value as JSON values; ``where`` names it in errors (e.g. ``DriveResult.goal``)."""
    if value is None:
        return None
    if isinstance(value, enum.Enum):
        return _encode_value(value.value, where)
    if isinstance(value, np.generic):
        return _encode_value(value.item(), where)
    if isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if is_dataclass(value) and not isinstance(value, type):
        return _encode_dataclass(value, where)
    if isinstance(value, np.ndarray):
        return _encode_value(value.tolist(), where)
    if isinstance(value, Mapping):
        return _encode_mapping(value, where)
    if isinstance(value, list | tuple):
        return [_encode_value(v, f"{where}[{k}]") for k, v in enumerate(value)]
    raise TypeError(f"{where}: cannot encode a {type(value).__name__} as JSON ({value!r:.80})")


def _encode_dataclass(obj: Any, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {TYPE_KEY: type(obj).__name__}
    for f in fields(obj):
        out[f.name] = _encode_value(getattr(obj, f.name), f"{where}.{f.name}")
    return out


def _encode_mapping(mapping: Mapping[Any, Any], where: str) -> dict[str, Any]:
    return {_encode_key(k, where): _encode_value(v, f"{where}[{k!r}]") for k, v in mapping.items()}


def _encode_key(key: Any, where: str) -> str:
    if isinstance(key, enum.Enum):
        key = key.value
    if isinstance(key, np.generic):
        key = key.item()
    if isinstance(key, str | int) and not isinstance(key, bool):
        return str(key)
    raise TypeError(f"{where}: a mapping key must be a str or an int, got {type(key).__name__}")


# --- decoding ------------------------------------------------------------------------------


def decode(data: Mapping[str, Any]) -> object:
    """The record a dict from :func:`encode` (possibly through JSON) stands for.

    A dict whose ``"_type"`` is missing or names no class of :data:`RECORD_TYPES` comes back
    unchanged. Raises ValueError, naming the field and the type, for a dict that does not
    fit its class.
    """
    if not isinstance(data, Mapping):
        raise TypeError(f"decode expects a dict, got {type(data).__name__}")
    name = data.get(TYPE_KEY)
    cls = RECORD_TYPES.get(name) if isinstance(name, str) else None
    if cls is None:
        return data
    return _decode_dataclass(cls, data, cls.__name__)


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    """The resolved annotations of a dataclass's fields set by its constructor."""
    hints = get_type_hints(cls)
    return {f.name: hints.get(f.name, Any) for f in fields(cls) if f.init}


def _decode_dataclass(cls: type, data: Any, where: str) -> Any:
    if not isinstance(data, Mapping):
        raise ValueError(f"{where}: expected an object for a {cls.__name__}, got {data!r:.80}")
    named = data.get(TYPE_KEY, cls.__name__)
    if named != cls.__name__:
        raise ValueError(f"{where}: expected a {cls.__name__}, got {TYPE_KEY}={named!r}")
    types_ = _field_types(cls)
    unknown = sorted(set(data) - set(types_) - {TYPE_KEY})
    if unknown:
        raise ValueError(f"{where}: {cls.__name__} has no field(s) {unknown}")
    kwargs = {}
    for f in fields(cls):
        if f.name not in types_:
            continue
        if f.name in data:
            kwargs[f.name] = _decode_value(data[f.name], types_[f.name], f"{where}.{f.name}")
        elif f.default is MISSING and f.default_factory is MISSING:
            raise ValueError(f"{where}.{f.name}: missing (a {cls.__name__} needs it)")
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: not a valid {cls.__name__}: {exc}") from exc


def _decode_value(value: Any, hint: Any, where: str) -> Any:
    """A JSON value as the annotated type ``hint``."""
    origin = get_origin(hint)
    if hint is Any:
        return value
    if origin in (Union, types.UnionType):
        return _decode_union(value, get_args(hint), where)
    if hint is np.ndarray or origin is np.ndarray:
        return _decode_array(value, hint, where)
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        return _decode_enum(value, hint, where)
    if isinstance(hint, type) and is_dataclass(hint):
        return _decode_dataclass(hint, value, where)
    if hint in (float, int, bool, str):
        return _decode_scalar(value, hint, where)
    if origin is tuple:
        return _decode_tuple(value, get_args(hint), where)
    if origin in (dict, Mapping) and not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected an object, got {value!r:.80}")
    if origin is list and not isinstance(value, list):
        raise ValueError(f"{where}: expected a list, got {value!r:.80}")
    return value


def _decode_union(value: Any, args: tuple[Any, ...], where: str) -> Any:
    if value is None and type(None) in args:
        return None
    rest = [a for a in args if a is not type(None)]
    if len(rest) == 1:
        return _decode_value(value, rest[0], where)
    return value


def _decode_scalar(value: Any, hint: type, where: str) -> Any:
    if hint is float:
        if value is None:
            return math.nan
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
    elif hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif isinstance(value, hint):
        return value
    raise ValueError(f"{where}: expected a {hint.__name__}, got {value!r:.80}")


def _decode_enum(value: Any, hint: type[enum.Enum], where: str) -> enum.Enum:
    try:
        return hint(value)
    except ValueError:
        allowed = [m.value for m in hint]
        raise ValueError(
            f"{where}: {value!r:.80} is not a {hint.__name__} (expected one of {allowed})"
        ) from None


def _decode_tuple(value: Any, args: tuple[Any, ...], where: str) -> tuple[Any, ...]:
    if not isinstance(value, list | tuple):
        raise ValueError(f"{where}: expected a list, got {value!r:.80}")
    if len(args) == 2 and args[1] is Ellipsis:
        item_types = [args[0]] * len(value)
    elif args:
        if len(args) != len(value):
            raise ValueError(f"{where}: expected {len(args)} items, got {len(value)}")
        item_types = list(args)
    else:
        item_types = [Any] * len(value)
    return tuple(
        _decode_value(v, t, f"{where}[{k}]")
        for k, (v, t) in enumerate(zip(value, item_types, strict=True))
    )


def _decode_array(value: Any, hint: Any, where: str) -> NDArray:
    """(Nested) lists as an array; ``None`` is NaN in float arrays."""
    dtype = _array_dtype(hint)
    try:
        if np.issubdtype(dtype, np.floating):
            return np.array(_none_to_nan(value), dtype=dtype)
        return np.array(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: not an array of {dtype}: {exc}") from exc


def _array_dtype(hint: Any) -> np.dtype:
    """The dtype an ``NDArray[...]`` annotation asks for (float when it does not say)."""
    args = get_args(hint)
    if len(args) == 2:
        scalar = get_args(args[1])
        if scalar and isinstance(scalar[0], type) and issubclass(scalar[0], np.generic):
            return np.dtype(scalar[0])
    return np.dtype(float)


def _none_to_nan(value: Any) -> Any:
    if value is None:
        return math.nan
    if isinstance(value, list | tuple):
        return [_none_to_nan(v) for v in value]
    return value
