"""Which figures the report shows, and where they are drawn: no matplotlib, so that a process that only
assembles the report (the session at its end) never loads the drawing code.

What a declared comparison varies is read from the compared configurations' settings (`comparison_axis`;
the labels and axes: docs/report.md "Comparisons").

`figure_jobs(data)` lists every figure as (id, kind, arguments), in document order; `report.figures` draws
a job by its kind. `assemble_figures(data)` has them drawn: elsewhere (`draw`), or by the caller's process
and worker processes (`here`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypeAlias

from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.model import Configuration, ReportData, factor_names
from protocol_runner.report.settings_view import TRAJECTORY, axis_label, format_quantity

FigureJob: TypeAlias = tuple[str, str, tuple[object, ...]]
"""A figure: its id (an HTML element id), its kind (`figures.DRAW`) and the arguments to draw it."""

Drawn: TypeAlias = tuple[str, str | None, str | None]
"""A drawn figure: its id, its data URI (None if it could not be drawn) and why not."""


@dataclass(frozen=True)
class FigureSet:
    """Figure id -> data URI, plus ids whose figure could not be drawn (with the reason)."""

    images: dict[str, str] = field(default_factory=dict)
    missing: dict[str, str] = field(default_factory=dict)


def figure_jobs(data: ReportData) -> list[FigureJob]:
    """Every figure the report shows for `data`, in document order."""
    jobs: list[FigureJob] = []
    for set_name in sorted({c.set_name for c in data.calibration}):
        checks = [c for c in data.calibration if c.set_name == set_name]
        jobs.append((f"fig-calibration-{slug(set_name)}", "calibration", (set_name, checks)))
    for key in data.keys:
        jobs.extend(configuration_jobs(data.joint_configurations(key)))
    for comp in distinct_comparisons(data):
        jobs.append((f"fig-comparison-{slug(comp.name)}-overlay", "comparison_overlay", (data, comp)))
        jobs.append((f"fig-comparison-{slug(comp.name)}-energy", "energy_bars", (data, comp)))
    if data.references:
        jobs.append(("fig-reference", "reference", (data,)))
    for comp in model_comparisons(data):
        jobs.append((f"fig-elements-{slug(comp.name)}", "element_fit", (data, comp)))
    return jobs


def configuration_jobs(cfgs: Sequence[Configuration]) -> list[FigureJob]:
    """The figures of one configuration, from its joints' parts `cfgs` (one for a single joint; none before
    its first trial): each kind drawn for every joint, and with several joints the first two joints' angles
    against each other."""
    if not cfgs or not any(cfg.trials for cfg in cfgs):
        return []
    base = f"fig-config-{cfgs[0].key}"
    kinds = ["hysteresis", "time", "energy"]
    kinds += ["phase"] if len(cfgs) > 1 else []
    kinds += ["boucwen"] if any(cfg.bouc_wen is not None for cfg in cfgs) else []
    return [(f"{base}-{kind}", kind, (tuple(cfgs),)) for kind in kinds]


def figure_ids(data: ReportData) -> list[str]:
    """Ids of every figure the report shows for `data`, in document order."""
    return [figure_id for figure_id, _, _ in figure_jobs(data)]


def configurations_of(data: ReportData, keys: Sequence[int], joint: str | None = None) -> list[Configuration]:
    """Joint `joint`'s part (None: the first joint's) of each configuration `keys` the archive holds."""
    return [c for k in keys if (c := data.configuration(k, joint)) is not None]


def distinct_comparisons(data: ReportData) -> list[Comparison]:
    """Declared comparisons drawn as overlays and energy figures: those with a configuration present,
    each set of configurations once (a protocol may list the same keys under two sections)."""
    seen: set[tuple[int, ...]] = set()
    out = []
    for comp in data.comparisons:
        key = tuple(sorted(comp.configurations))
        if key in seen or not configurations_of(data, comp.configurations):
            continue
        seen.add(key)
        out.append(comp)
    return out


def model_comparisons(data: ReportData) -> list[Comparison]:
    """The comparisons that change a fitted elastic element of some joint (`fitted_elements_differ`): the
    elastic model against the midline for each (as thesis Figures 52-53)."""
    return [
        comp
        for comp in distinct_comparisons(data)
        if any(
            fitted_elements_differ(configurations_of(data, comp.configurations, joint))
            for joint in (data.joints if data.multi_joint else (None,))
        )
    ]


def fitted_elements_differ(configs: Sequence[Configuration]) -> bool:
    """True when at least one configuration has a drawable element fit and the fitted elements' declared
    parameters (the device as configured) differ between the configurations: the comparison changes
    the elastic model, so drawing the fits side by side shows the model following the change."""
    fitted: list[str] = []
    for cfg in configs:
        if cfg.element_fit is not None and cfg.element_fit.drawable:
            names = [e.name for e in cfg.element_fit.elements]
            names += [key.split(".", 1)[0] for key, _ in cfg.element_fit.parameters]
            fitted.extend(n for n in names if n not in fitted)
    if not fitted:
        return False
    for name in fitted:
        params = set()
        for cfg in configs:
            element = cfg.settings.element(name)
            params.add(repr(element.params) if element is not None else "")
        if len(params) > 1:
            return True
    return False


def slug(text: str) -> str:
    """An HTML-id-safe version of `text`."""
    out = "".join(ch if ch.isalnum() else "-" for ch in text.lower()).strip("-")
    return out or "x"


def default_workers(n_tasks: int) -> int:
    """Worker processes for `n_tasks` figures: 2 when there are enough figures and cores, else 1."""
    if n_tasks < 40:
        return 1
    return max(1, min(2, os.cpu_count() or 1))


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
