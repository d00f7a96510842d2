"""A configuration's declared settings as the archive stores them (`settings_json` and `device_json`, in
declaration order, and `trajectory_name`: docs/archive.md "Configurations"; without them, empty settings),
for the whole report.

Nothing here assumes any factor, level or quantity name: a quantity's unit comes from its name's suffix
(`friction_nm` -> N·m).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.settings import LevelLookup
from protocol_runner.protocol.units import UNIT_SUFFIXES, unit_suffix
from protocol_runner.report.h5read import attr_str

Quantity = float | tuple[float, ...]
Param = Quantity | str | tuple[str, ...]  # an element parameter (words for constants and lists such as `fit`)


#: Display label of each quantity-name unit suffix: the protocol's registry (protocol/units.py) as a reader
#: writes it (`N*m` -> `N·m`, `deg/s^2` -> `deg/s²`).
UNIT_LABELS: Mapping[str, str] = {s: u.replace("*", "·").replace("^2", "²") for s, u in UNIT_SUFFIXES.items()}

#: The comparison parameter that compares trajectories rather than a factor's levels.
TRAJECTORY = "trajectory"


def unit_label(name: str) -> str:
    """The unit of `name` as a reader writes it (`stiffness_n_per_mm` -> "N/mm"); "" when dimensionless."""
    return UNIT_LABELS.get(unit_suffix(name) or "", "")


def quantity_title(name: str) -> str:
    """`name` without its unit suffix, words spaced (`range_deg` -> "range", `screw_turns` -> "screw")."""
    suffix = unit_suffix(name)
    stem = name[: -len(suffix)] if suffix else name
    return stem.replace("_", " ").strip() or name


def axis_label(factor: str, quantity: str) -> str:
    """An axis label naming the factor, the quantity and its unit: "friction: friction (N·m)"."""
    unit = unit_label(quantity)
    text = f"{factor}: {quantity_title(quantity)}"
    return f"{text} ({unit})" if unit else text


def format_number(value: float) -> str:
    """A quantity's number, short: 3.75, 40, 0.001 (no trailing zeros; NaN as an em dash)."""
    if not math.isfinite(value):
        return "—"
    return f"{value:g}"


def format_quantity(name: str, value: Quantity | str, *, unit: bool = True) -> str:
    """A quantity with its unit: "3.75 N·m"; a range [lo, hi] as "40–90 deg"; a longer list "1, 2, 3 mm"."""
    if isinstance(value, str):
        return value
    if isinstance(value, tuple):
        sep = "–" if len(value) == 2 else ", "
        text = sep.join(format_number(v) for v in value)
    else:
        text = format_number(value)
    label = unit_label(name) if unit else ""
    if not label:
        return text
    return f"{text}{label}" if label == "%" else f"{text} {label}"


@dataclass(frozen=True)
class FactorLevel:
    """One declared factor of a configuration: its level label and the quantities it resolves to."""

    factor: str
    level: str
    quantities: tuple[tuple[str, Quantity], ...]

    def quantity(self, name: str) -> Quantity | None:
        """The value of quantity `name`, or None when the level has none."""
        return dict(self.quantities).get(name)

    def text(self) -> str:
        """The level and its quantities: "R1 (range 40–90 deg)"."""
        if not self.quantities:
            return self.level
        inner = ", ".join(f"{quantity_title(q)} {format_quantity(q, v)}" for q, v in self.quantities)
        return f"{self.level} ({inner})"


@dataclass(frozen=True)
class DeviceElement:
    """One element of the device under test with its resolved parameters (`device_json`)."""

    name: str
    type: str
    params: tuple[tuple[str, Param], ...]


@dataclass(frozen=True)
class SettingsView(LevelLookup):
    """The settings of one configuration: its factors (declaration order), device and trajectory name."""

    factors: tuple[FactorLevel, ...] = ()
    device: tuple[DeviceElement, ...] = ()
    trajectory: str = ""

    def factor_names(self) -> tuple[str, ...]:
        """The factors this configuration sets, in declaration order."""
        return tuple(f.factor for f in self.factors)

    def factor(self, name: str) -> FactorLevel | None:
        """The setting of factor `name`, or None when the configuration does not set it."""
        return next((f for f in self.factors if f.factor == name), None)

    def element(self, name: str) -> DeviceElement | None:
        """The device element called `name`, or None."""
        return next((e for e in self.device if e.name == name), None)

    def flat(self) -> dict[str, Quantity | str]:
        """The archive's flattened form: `<factor>` -> level label, `<factor>.<quantity>` -> value."""
        out: dict[str, Quantity | str] = {}
        for f in self.factors:
            out[f.factor] = f.level
            for q, v in f.quantities:
                out[f"{f.factor}.{q}"] = v
        return out

    def levels(self) -> tuple[tuple[str, str], ...]:
        """(factor, level label) pairs in declaration order."""
        return tuple((f.factor, f.level) for f in self.factors)


def _number(value: Any, where: str) -> Quantity:
    if isinstance(value, bool):
        raise InvalidInput(f"{where}: {value!r} is not a number")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, Sequence) and not isinstance(value, str):
        return tuple(float(_number(v, where)) for v in value)  # type: ignore[arg-type]
    raise InvalidInput(f"{where}: {value!r} is not a number or a list of numbers")


def _param(value: Any) -> Param:
    """An element parameter: a number, a list of numbers (tuple), a word, or a list of words (e.g. the
    element's `fit` list); anything else as its JSON text."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        if all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            return tuple(float(v) for v in value)
        if all(isinstance(v, str) for v in value):
            return tuple(str(v) for v in value)
    return json.dumps(value)


def _json(attrs: Mapping[str, Any], name: str, where: str) -> Any:
    try:
        return json.loads(attr_str(attrs, name))
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{where}: attribute {name} is not valid JSON ({exc.msg})") from None


def settings_from_attrs(attrs: Mapping[str, Any], where: str) -> SettingsView:
    """The settings of a configuration group from its attributes; `where` names it in errors.

    Raises `InvalidInput` when `settings_json` or `device_json` is not the documented JSON shape.
    """
    factors: list[FactorLevel] = []
    if "settings_json" in attrs:
        doc = _json(attrs, "settings_json", where)
        if not isinstance(doc, dict):
            raise InvalidInput(f"{where}: attribute settings_json must be a JSON object of factors")
        for factor, entry in doc.items():
            if not isinstance(entry, dict) or "level" not in entry:
                raise InvalidInput(f"{where}: settings_json.{factor} must be an object with a 'level'")
            quantities = tuple(
                (str(q), _number(v, f"{where}: settings_json.{factor}.{q}"))
                for q, v in entry.items()
                if q != "level"
            )
            factors.append(FactorLevel(str(factor), str(entry["level"]), quantities))
    device: list[DeviceElement] = []
    if "device_json" in attrs:
        doc = _json(attrs, "device_json", where)
        if not isinstance(doc, list):
            raise InvalidInput(f"{where}: attribute device_json must be a JSON list of elements")
        for i, entry in enumerate(doc):
            if not isinstance(entry, dict) or "name" not in entry or "type" not in entry:
                raise InvalidInput(f"{where}: device_json[{i}] must be an object with 'name' and 'type'")
            params = tuple((str(k), _param(v)) for k, v in entry.items() if k not in ("name", "type"))
            device.append(DeviceElement(str(entry["name"]), str(entry["type"]), params))
    return SettingsView(tuple(factors), tuple(device), attr_str(attrs, "trajectory_name"))


def elements_from_json(text: str, where: str) -> tuple[DeviceElement, ...]:
    """Device elements from a JSON list text (`device_json`, a fit's `elements_json`)."""
    return settings_from_attrs({"device_json": text}, where).device
