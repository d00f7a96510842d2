"""The protocol's factors (levels and their quantities, with units) and the device under test (its
elements, per driven joint): pydantic models. Nothing here names a campaign; cross-field checks (levels that
exist, bindings whose units match) live in `protocol/validate.py` and `protocol/resolve.py`."""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import BeforeValidator, ConfigDict, Field, model_validator

from protocol_runner.protocol.schema_base import Identifier, LevelName, _Model, _str_keys
from protocol_runner.protocol.units import compound_unit_problem, known_suffixes, unit_suffix

# ----------------------------------------------------------------------------------------- factors

RESERVED_LEVEL_KEYS = ("same_as", "description", "setup")
Quantity = float | tuple[float, ...]


def _quantity_value(name: str, value: object) -> Quantity:
    if isinstance(value, bool) or not isinstance(value, int | float | list | tuple):
        raise ValueError(f"quantity {name!r} must be a number or a list of numbers, got {value!r}")
    if isinstance(value, list | tuple):
        items = [_quantity_value(name, v) for v in value]
        if not items or any(isinstance(v, tuple) for v in items):
            raise ValueError(f"quantity {name!r} must be a number or a flat list of numbers, got {value!r}")
        if name.endswith("range_deg") and not (len(items) == 2 and items[0] < items[1]):  # type: ignore[operator]
            raise ValueError(f"{name} must be [low, high] with low < high, got {value!r}")
        return tuple(float(v) for v in items)  # type: ignore[arg-type]
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"quantity {name!r} must be finite, got {value!r}")
    return number


class LevelSpec(_Model):
    """One level of a factor: quantities (keys ending with a unit suffix, protocol/units.py), or
    `same_as` another level of the same factor; `description` and `setup` (operator checklist text)."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    same_as: LevelName | None = None
    description: str = ""
    setup: str = ""

    @model_validator(mode="before")
    @classmethod
    def _quantities(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        out = dict(data)
        for key, value in data.items():
            if key in RESERVED_LEVEL_KEYS:
                continue
            if unit_suffix(str(key)) is None:
                raise ValueError(
                    f"{key!r}: a quantity's name must end with a unit suffix ({known_suffixes()}); "
                    f"reserved keys: {', '.join(RESERVED_LEVEL_KEYS)}"
                )
            compound = compound_unit_problem(str(key))
            if compound is not None:
                raise ValueError(compound)
            out[key] = _quantity_value(str(key), value)
        return out

    @property
    def quantities(self) -> tuple[tuple[str, Quantity], ...]:
        return tuple((k, v) for k, v in (self.model_extra or {}).items())


Factor = Annotated[dict[str, LevelSpec], BeforeValidator(_str_keys), Field(min_length=1)]

# ------------------------------------------------------------------------------------------- device


class ElementSpec(_Model):
    """One element of the device: `name`, `type` (models/elements.py ELEMENT_TYPES) and its parameters,
    each a constant or a binding "<factor>.<quantity>" (checked in protocol/resolve.py)."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    name: Identifier
    type: str

    @property
    def params(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class JointDeviceSpec(_Model):
    """The elements one driven joint carries (a multi-joint protocol's `device.joints.<joint>`)."""

    description: str = ""
    elements: list[ElementSpec] = Field(min_length=1)


class DeviceSpec(_Model):
    """The device under test: `elements` (one driven joint), or `joints: {<joint>: {elements: [...]}}`
    (a multi-joint protocol: each driven joint its own elements; a joint may carry none)."""

    name: str = ""
    description: str = ""
    elements: list[ElementSpec] = Field(default_factory=list)
    joints: dict[Identifier, JointDeviceSpec] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _one_form(self) -> Any:
        if bool(self.elements) == bool(self.joints):
            raise ValueError("give exactly one of `elements` (one joint) and `joints` (elements per joint)")
        return self

    def located_elements(self) -> list[tuple[str, tuple[str | int, ...], ElementSpec]]:
        """(joint or "", YAML location, element) for every element, in file order."""
        if self.elements:
            return [("", ("device", "elements", i), el) for i, el in enumerate(self.elements)]
        return [
            (joint, ("device", "joints", joint, "elements", i), el)
            for joint, spec in self.joints.items()
            for i, el in enumerate(spec.elements)
        ]
