"""What a declared comparison varies, read from the compared configurations' settings (docs/report.md
"Comparisons"): the factor's level label and the value of its axis quantity, on a numeric axis when every
configuration has a finite scalar value of it; other factors whose level also differs within the
comparison are added to each label. With "trajectory", the label is the configuration's trajectory name
(its profile when unnamed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.model import Configuration, factor_names
from protocol_runner.report.settings_view import (
    TRAJECTORY,
    axis_label,
    format_quantity,
)


@dataclass(frozen=True)
class ComparisonAxis:
    """How a comparison's configurations are placed and labelled."""

    parameter: str
    quantity: str  # the factor's axis quantity ("" for "trajectory" or a factor without quantities)
    numeric: bool  # True when every configuration has a finite scalar value of `quantity`
    label: str  # axis label with the unit
    others: tuple[str, ...]  # other factors whose level differs within the comparison

    def value(self, cfg: Configuration) -> float:
        """The configuration's numeric x value (NaN when the axis is not numeric)."""
        if not self.numeric:
            return math.nan
        v = cfg.quantity(self.parameter, self.quantity)
        return float(v) if isinstance(v, float) else math.nan

    def value_text(self, cfg: Configuration) -> str:
        """The configuration's value on this axis as text: level label and quantity with its unit."""
        if self.parameter == TRAJECTORY:
            return cfg.settings.trajectory or cfg.profile
        level = cfg.level(self.parameter)
        if level is None:
            return ""
        if not self.quantity:
            return level
        v = cfg.quantity(self.parameter, self.quantity)
        return f"{level} ({format_quantity(self.quantity, v)})" if v is not None else level

    def tick_label(self, cfg: Configuration) -> str:
        """A short two-line bar label: the level (and the other differing factors' levels), then the axis
        quantity's value with its unit (the bar itself carries the configuration key)."""
        if self.parameter == TRAJECTORY:
            head, value = self.value_text(cfg), ""
        else:
            head = cfg.level(self.parameter) or ""
            v = cfg.quantity(self.parameter, self.quantity) if self.quantity else None
            value = format_quantity(self.quantity, v) if v is not None else ""
        others = " · ".join(str(cfg.level(f)) for f in self.others if cfg.level(f) is not None)
        first = " · ".join(p for p in (head, others) if p) or f"config {cfg.key}"
        return f"{first}\n{value}" if value else first

    def config_label(self, cfg: Configuration) -> str:
        """Legend or tick text: key, the compared value, then the other differing factors' levels."""
        parts = [self.value_text(cfg)]
        parts.extend(f"{f} {cfg.level(f)}" for f in self.others if cfg.level(f) is not None)
        text = ", ".join(p for p in parts if p)
        return f"{cfg.key}: {text}" if text else f"config {cfg.key}"


def _differs(values: Sequence[object]) -> bool:
    return len({repr(v) for v in values}) > 1


def comparison_axis(comparison: Comparison, configs: Sequence[Configuration]) -> ComparisonAxis:
    """The axis of `comparison` over `configs` (its configurations present in the archive)."""
    parameter = comparison.parameter
    others = tuple(
        f for f in factor_names(configs) if f != parameter and _differs([cfg.level(f) for cfg in configs])
    )
    if parameter == TRAJECTORY:
        return ComparisonAxis(parameter, "", False, "trajectory", others)
    names: list[str] = []
    for cfg in configs:
        setting = cfg.settings.factor(parameter)
        if setting is not None:
            names.extend(q for q, _ in setting.quantities if q not in names)
    if not names:
        return ComparisonAxis(parameter, "", False, parameter, others)
    quantity = next((q for q in names if _differs([cfg.quantity(parameter, q) for cfg in configs])), names[0])
    values = [cfg.quantity(parameter, quantity) for cfg in configs]
    numeric = bool(values) and all(isinstance(v, float) and math.isfinite(v) for v in values)
    return ComparisonAxis(parameter, quantity, numeric, axis_label(parameter, quantity), others)
