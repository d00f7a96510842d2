"""The device under test as composed physical elements: each of a protocol's `device:` elements built with
every parameter checked against its type (`element_types.ELEMENT_TYPES`) and the defaults filled in.

Sign convention (as `models.spring`): a positive torque is the torque the robot must apply towards +angle.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from protocol_runner.errors import InvalidInput

from .element_types import ELEMENT_TYPES, ElementKind, ParamSpec

ParamValue = float | tuple[float, ...] | str | tuple[str, ...]


@dataclass(frozen=True)
class Element:
    """One element of a device with every parameter resolved (defaults filled in) and checked."""

    name: str
    type: str
    params: Mapping[str, ParamValue] = field(hash=False)

    @property
    def kind(self) -> ElementKind:
        return ELEMENT_TYPES[self.type].kind

    def number(self, param: str) -> float:
        """A numeric parameter's value."""
        value = self.params[param]
        assert isinstance(value, float)
        return value

    def pair(self, param: str) -> tuple[float, float]:
        """A [lo, hi] parameter's value."""
        value = self.params[param]
        assert isinstance(value, tuple) and len(value) == 2
        return float(value[0]), float(value[1])

    @property
    def fit(self) -> tuple[str, ...]:
        """The parameters the element fit estimates (empty for non-elastic elements)."""
        value = self.params.get("fit", ())
        assert isinstance(value, tuple)
        return tuple(str(v) for v in value)

    def replace(self, **values: float) -> Element:
        """A copy with some numeric parameters changed (the fit's trial values); only those are checked
        again (the element fit calls this for every trial point of its optimizer)."""
        etype = ELEMENT_TYPES[self.type]
        params = dict(self.params)
        for key, value in values.items():
            spec = etype.parameters.get(key)
            if spec is None:
                return build_element(self.name, self.type, {**params, key: value})  # names the unknown key
            params[key] = _check_value(_where(self.name, self.type, key), spec, float(value), ())
        return Element(name=self.name, type=self.type, params=params)

    def to_json(self) -> dict[str, object]:
        """{"name", "type", every parameter} (tuples as lists), for the archive's elements_json."""
        out: dict[str, object] = {"name": self.name, "type": self.type}
        for key, value in self.params.items():
            out[key] = list(value) if isinstance(value, tuple) else value
        return out


def _where(name: str, type_: str, param: str) -> str:
    return f"element {name!r} ({type_}): parameter {param!r}"


def _number(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidInput(f"{where} must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InvalidInput(f"{where} must be finite, got {value!r}")
    return out


def _names(where: str, value: object, allowed: Sequence[str]) -> tuple[str, ...]:
    if isinstance(value, str):
        items = [v.strip() for v in value.replace(" ", ",").split(",") if v.strip()]
    elif isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        items = [str(v) for v in value]
    else:
        raise InvalidInput(f"{where} must be a list of parameter names, got {value!r}")
    for item in items:
        if item not in allowed:
            raise InvalidInput(
                f"{where}: {item!r} is not a fittable parameter (fittable: {', '.join(allowed)})"
            )
    return tuple(dict.fromkeys(items))


def _check_value(where: str, spec: ParamSpec, value: object, fittable: Sequence[str]) -> ParamValue:
    if spec.shape == "names":
        return _names(where, value, fittable)
    if spec.shape == "pair":
        if not isinstance(value, list | tuple) or len(value) != 2:
            raise InvalidInput(f"{where} must be a pair [lo, hi], got {value!r}")
        lo, hi = _number(where, value[0]), _number(where, value[1])
        if not lo < hi:
            raise InvalidInput(f"{where} must be [lo, hi] with lo < hi, got {list(value)!r}")
        return (lo, hi)
    number = _number(where, value)
    if spec.shape == "integer" and number != round(number):
        raise InvalidInput(f"{where} must be a whole number, got {value!r}")
    if spec.shape == "sign" and number not in (1.0, -1.0):
        raise InvalidInput(f"{where} must be +1 or -1, got {value!r}")
    if spec.bounds is not None and not spec.bounds[0] <= number <= spec.bounds[1]:
        raise InvalidInput(f"{where} must lie in [{spec.bounds[0]:g}, {spec.bounds[1]:g}], got {value!r}")
    return number


def build_element(name: str, type_: str, params: Mapping[str, object]) -> Element:
    """Check one element's parameters against its type and fill in the defaults. Raises InvalidInput
    naming the element and the parameter (unknown type or parameter, missing, wrong shape, out of bounds)."""
    etype = ELEMENT_TYPES.get(type_)
    if etype is None:
        raise InvalidInput(
            f"element {name!r}: unknown element type {type_!r} (known: {', '.join(sorted(ELEMENT_TYPES))})"
        )
    for key in params:
        if key not in etype.parameters:
            raise InvalidInput(
                f"{_where(name, type_, key)} is unknown (parameters of {type_}: {', '.join(etype.parameters)})"
            )
    fittable = [k for k, s in etype.parameters.items() if s.fittable]
    resolved: dict[str, ParamValue] = {}
    for key, spec in etype.parameters.items():
        value = params.get(key, spec.default)
        if value is None:
            raise InvalidInput(f"{_where(name, type_, key)} is required ({spec.doc})")
        resolved[key] = _check_value(_where(name, type_, key), spec, value, fittable)
    return Element(name=name, type=type_, params=resolved)


def _fields(item: object) -> tuple[str, str, Mapping[str, object]]:
    if isinstance(item, tuple) and len(item) == 3:
        name, type_, params = item
    else:
        name, type_, params = (getattr(item, "name"), getattr(item, "type"), getattr(item, "params"))  # noqa: B009
    if not isinstance(params, Mapping):
        params = dict(params)
    return str(name), str(type_), params


def build_device(elements: Sequence[object]) -> tuple[Element, ...]:
    """Elements from ElementSetting-like objects (.name, .type, .params as a mapping or (key, value) pairs)
    or (name, type, params) tuples; element names must be distinct. Raises InvalidInput."""
    out: list[Element] = []
    seen: set[str] = set()
    for item in elements:
        name, type_, params = _fields(item)
        if name in seen:
            raise InvalidInput(f"element {name!r}: two elements of the device have this name")
        seen.add(name)
        out.append(build_element(name, type_, params))
    return tuple(out)
