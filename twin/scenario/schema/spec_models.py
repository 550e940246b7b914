"""Pydantic models generated from the instruments' dataclasses, so that the scenario's
noise sections and the instruments stay in step."""

from __future__ import annotations

import dataclasses
import typing
from typing import Annotated

from pydantic import Field, create_model, model_validator

from twin.scenario.schema.frozen import Frozen


class SpecConfig(Frozen):
    """Base of the configs generated from instrument dataclasses (by
    :func:`model_from_dataclass`)."""

    _spec_cls: typing.ClassVar[type]

    def spec(self) -> typing.Any:
        """The dataclass instance these values describe."""
        return self._spec_cls(**{name: getattr(self, name) for name in type(self).model_fields})

    @model_validator(mode="after")
    def _spec_accepts(self) -> typing.Self:
        # The dataclass's own checks (ranges, consistency) run here, so a bad value is
        # reported with its key in the scenario file.
        self.spec()
        return self


def model_from_dataclass(
    cls: type,
    name: str,
    doc: str,
    ranges: dict[str, typing.Any],
    module: str,
    base: type[SpecConfig] = SpecConfig,
) -> type[SpecConfig]:
    """A frozen pydantic model called ``name`` (an attribute of that name of ``module``,
    so that scenarios pickle) with the fields, types and defaults of dataclass ``cls``, each
    field constrained by its entry of ``ranges`` (a ``Field(...)``; every field needs one,
    so that a field added to the dataclass gets a range too), on ``base`` (which may add
    checks between the fields)."""
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    if set(ranges) != set(names):
        raise TypeError(f"ranges of {name} must name exactly the fields {names}")
    fields: dict[str, typing.Any] = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = Field(default_factory=f.default_factory)
        else:
            default = ...
        fields[f.name] = (Annotated[hints[f.name], ranges[f.name]], default)
    model = create_model(name, __base__=base, __module__=module, **fields)
    model.__doc__ = doc
    model._spec_cls = cls
    return model
