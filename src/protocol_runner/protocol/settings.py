"""The physical settings of one configuration: a level per declared factor, and the device resolved.

`Settings` is what a configuration means once its level labels are looked up (through `same_as`) and the
device's element parameters bound to factor quantities are replaced by numbers. It is the plan's
`settings` / `device` (docs/protocol.md "Plan") and the archive's configuration attributes
(docs/archive.md). Nothing here knows any campaign's factor names.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Protocol

Quantity = float | tuple[float, ...]


@dataclass(frozen=True)
class FactorSetting:
    """One factor of a configuration: the level label the configuration names (not its `same_as` target)
    and the quantities it resolves to, in declaration order."""

    level: str
    quantities: tuple[tuple[str, Quantity], ...]
    description: str = ""
    setup: str = ""

    def quantity(self, name: str) -> Quantity | None:
        return dict(self.quantities).get(name)


@dataclass(frozen=True)
class ElementSetting:
    """One element of the device under test with every parameter resolved (ranges as tuples; a str only
    for a constant word)."""

    name: str
    type: str
    params: tuple[tuple[str, Quantity | str], ...]
    joint: str = ""  # the driven joint that carries it (multi-joint protocols; "" for one joint)

    def to_json(self) -> dict[str, Any]:
        joint = {"joint": self.joint} if self.joint else {}
        return {"name": self.name, "type": self.type, **joint, **{k: _plain(v) for k, v in self.params}}


class _Level(Protocol):
    @property
    def level(self) -> str: ...

    def quantity(self, name: str) -> Quantity | None: ...


class LevelLookup:
    """A configuration's `level` and `quantity` of a factor, through its `factor` (the plan's `Settings`
    and the report's `SettingsView`, read back from an archive, answer alike)."""

    def factor(self, name: str) -> _Level | None:
        raise NotImplementedError

    def level(self, factor: str) -> str | None:
        """The level label of `factor`, or None when the configuration does not set it."""
        f = self.factor(factor)
        return f.level if f is not None else None

    def quantity(self, factor: str, name: str) -> Quantity | None:
        """The value of `factor`'s quantity `name`, or None."""
        f = self.factor(factor)
        return f.quantity(name) if f is not None else None


@dataclass(frozen=True)
class Settings(LevelLookup):
    """A configuration's settings: the factors it sets (declared order) and its resolved device."""

    factors: tuple[tuple[str, FactorSetting], ...]
    device: tuple[ElementSetting, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The plan's `settings`: {"<factor>": {"level": label, **quantities}}."""
        return {
            name: {"level": f.level, **{q: _plain(v) for q, v in f.quantities}} for name, f in self.factors
        }

    def factor(self, factor: str) -> FactorSetting | None:
        return dict(self.factors).get(factor)

    def device_json(self) -> list[dict[str, Any]]:
        """The plan's `device`: [{"name": ..., "type": ..., **params}] in declaration order."""
        return [e.to_json() for e in self.device]

    def device_of(self, joint: str) -> tuple[ElementSetting, ...]:
        """The elements `joint` carries (every element of a single-joint device)."""
        return tuple(e for e in self.device if not e.joint or e.joint == joint)

    def factor_names(self) -> list[str]:
        return [name for name, _ in self.factors]

    def summary(self) -> str:
        """`factor=level` pairs, e.g. for messages and tables."""
        return ", ".join(f"{name} {f.level}" for name, f in self.factors)


def _plain(value: Quantity | str) -> Any:
    return list(value) if isinstance(value, tuple) else value


def configuration_attributes(settings: Settings) -> dict[str, Any]:
    """The setting attributes of an archive configuration group (docs/archive.md): `factors`,
    `settings_json`, `device_json`, and per factor `<factor>` = level label and `<factor>.<quantity>`."""
    out: dict[str, Any] = {
        "factors": settings.factor_names(),
        "settings_json": json.dumps(settings.to_json()),
        "device_json": json.dumps(settings.device_json()),
    }
    for name, f in settings.factors:
        out[name] = f.level
        for q, v in f.quantities:
            out[f"{name}.{q}"] = [float(x) for x in v] if isinstance(v, tuple) else float(v)
    return out
