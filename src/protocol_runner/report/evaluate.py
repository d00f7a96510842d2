"""One generic evaluator: a declared expectation and an archive's data give a verdict with its numbers.

Decision rule (docs/protocol.md "Expectations"), always on trial values (one per trial, the experimental
unit) with 95 % intervals (`analysis.statistics`):

- every configuration involved needs `min_trials` trials with the metric, else `not evaluable`;
- `increasing` / `decreasing`: the means move the stated way at every step of the stated order, and the
  Welch interval of last minus first excludes zero on that side;
- `no_trend`: neither `increasing` nor `decreasing` is met;
- `greater` / `less` than configurations (`than`, pairwise): each Welch interval of the difference lies
  wholly above (below) zero; than a `value`: each t-interval of the mean lies wholly above (below) it;
- `equal` within `tolerance`: each interval (difference, or mean minus `value`) lies inside ±tolerance;
- `inside` `[low, high]` (two-sided): each configuration's t-interval of the mean lies inside it.

With `baseline` (and `than_baseline`), each configuration's value is its mean minus its baseline's: what a
setting adds over a baseline. The interval is then the Welch-Satterthwaite interval of the contrast
(`analysis.statistics.contrast_interval`), e.g. (5 - 1) - (6 - 2) for "the brake adds the same loss at
both speeds".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

from protocol_runner.analysis.statistics import (
    TInterval,
    WelchInterval,
    contrast_interval,
    t_interval,
    welch_interval,
)
from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.report.metrics import LABELS, UNITS, trial_values
from protocol_runner.report.model import ReportData

MET, NOT_MET, NOT_EVALUABLE = "met", "not met", "not evaluable"


@dataclass(frozen=True)
class Evidence:
    """One configuration's metric: trials and the mean with its 95 % interval."""

    key: int
    n: int
    mean: float
    low: float
    high: float


@dataclass(frozen=True)
class Verdict:
    """The outcome of one expectation, with the numbers that decided it."""

    spec: ExpectationSpec
    verdict: str
    reason: str
    evidence: tuple[Evidence, ...]

    @property
    def css(self) -> str:
        """`met`, `not-met` or `not-evaluable` (HTML attribute form)."""
        return self.verdict.replace(" ", "-")

    @property
    def unit(self) -> str:
        """The metric's unit."""
        return UNITS[self.spec.metric]


def _fmt(value: float) -> str:
    return f"{value:.3g}" if abs(value) < 1 else f"{value:.2f}" if abs(value) < 100 else f"{value:.1f}"


def _ival(low: float, high: float, unit: str) -> str:
    return f"[{_fmt(low)}, {_fmt(high)}] {unit}"


def metric_label(spec: ExpectationSpec) -> str:
    """Readable metric name with its argument, e.g. "angle percentile 99"."""
    label = LABELS[spec.metric]
    if spec.metric == "angle_percentile":
        return f"{label} {spec.percentile:g}"
    if spec.metric == "hysteresis_width":
        return f"{label} at {spec.angle_deg:g}°"
    return label


def evaluate_expectation(spec: ExpectationSpec, data: ReportData) -> Verdict:
    """The verdict of `spec` on `data` (never raises for missing data: `not evaluable` says why)."""
    unit = UNITS[spec.metric]
    keys = list(
        dict.fromkeys(
            [*spec.configurations, *(spec.baseline or []), *(spec.than or []), *(spec.than_baseline or [])]
        )
    )
    values: dict[int, tuple[float, ...]] = {}
    intervals: dict[int, TInterval] = {}
    for key in keys:
        cfg = data.configuration(key)
        vals = (
            ()
            if cfg is None
            else trial_values(cfg, spec.metric, percentile=spec.percentile, angle_deg=spec.angle_deg)
        )
        values[key] = vals
        intervals[key] = t_interval(vals)
    evidence = tuple(Evidence(k, i.n, i.mean, i.low, i.high) for k, i in intervals.items())
    short = [k for k in keys if intervals[k].n < spec.min_trials]
    if short:
        parts = [
            f"configuration {k} is not in this archive"
            if data.configuration(k) is None
            else f"configuration {k} has {intervals[k].n or 'no'} trial{'' if intervals[k].n == 1 else 's'} "
            f"with {metric_label(spec)}"
            for k in short
        ]
        need = f"the rule needs {spec.min_trials} per configuration"
        return Verdict(spec, NOT_EVALUABLE, "; ".join(parts) + f" ({need}).", evidence)
    met, reason = _decide(spec, values, intervals, unit)
    return Verdict(spec, MET if met else NOT_MET, reason, evidence)


def evaluate_all(specs: Sequence[ExpectationSpec], data: ReportData) -> tuple[Verdict, ...]:
    """Every declared expectation's verdict, in declaration order."""
    return tuple(evaluate_expectation(s, data) for s in specs)


def _trend(
    spec: ExpectationSpec,
    values: dict[int, tuple[float, ...]],
    intervals: dict[int, TInterval],
    sign: float,
    unit: str,
) -> tuple[bool, str]:
    order = spec.configurations
    means = [intervals[k].mean for k in order]
    steps = all(sign * (b - a) > 0 for a, b in pairwise(means))
    end: WelchInterval = welch_interval(values[order[0]], values[order[-1]])
    ends = (end.low > 0) if sign > 0 else (end.high < 0)
    arrow = " < " if sign > 0 else " > "
    text = (
        f"means in order {arrow.join(_fmt(m) for m in means)} {unit}; configuration {order[-1]} minus "
        f"{order[0]}: {_fmt(end.difference)} {unit}, 95 % Welch interval {_ival(end.low, end.high, unit)}"
    )
    if not steps:
        text += "; not every step goes the stated way"
    elif not ends:
        text += "; the interval does not exclude zero"
    return steps and ends, text


def _decide(
    spec: ExpectationSpec, values: dict[int, tuple[float, ...]], intervals: dict[int, TInterval], unit: str
) -> tuple[bool, str]:
    r = spec.relation
    if r in ("increasing", "decreasing"):
        return _trend(spec, values, intervals, 1.0 if r == "increasing" else -1.0, unit)
    if r == "no_trend":
        up, up_text = _trend(spec, values, intervals, 1.0, unit)
        down, _ = _trend(spec, values, intervals, -1.0, unit)
        return not (up or down), up_text.split(";")[0] + (
            "; a clear trend" if up or down else "; no step-by-step trend with an interval excluding zero"
        )
    parts: list[str] = []
    ok = True
    for i, key in enumerate(spec.configurations):
        terms, name = _terms(spec, i, key)
        if len(terms) == 1:
            ti = intervals[key]
            low, high = ti.low, ti.high
            subject = f"configuration {key}: mean {_fmt(ti.mean)} {unit}, 95 % interval"
        else:
            c = contrast_interval([(w, values[k]) for w, k in terms])
            low, high = c.low, c.high
            kind = "Welch" if len(terms) == 2 else "Welch-Satterthwaite"
            subject = f"{name}: {_fmt(c.difference)} {unit}, 95 % {kind} interval"
        ref = 0.0 if spec.than is not None else spec.value or 0.0
        this_ok = _holds(spec, low, high, ref)
        ok = ok and this_ok
        parts.append(f"{subject} {_ival(low, high, unit)}{'' if this_ok else ' (fails)'}")
    return ok, "; ".join(parts) + _criterion(spec, unit)


def _terms(spec: ExpectationSpec, i: int, key: int) -> tuple[list[tuple[float, int]], str]:
    """The weighted configurations of the i-th statement and its readable name."""
    terms: list[tuple[float, int]] = [(1.0, key)]
    name = f"configuration {key}"
    if spec.baseline is not None:
        terms.append((-1.0, spec.baseline[i]))
        name = f"configuration {key} minus {spec.baseline[i]}"
    if spec.than is not None:
        other = spec.than[i]
        terms.append((-1.0, other))
        if spec.than_baseline is not None:
            terms.append((1.0, spec.than_baseline[i]))
            name = f"({name.removeprefix('configuration ')}) minus ({other} minus {spec.than_baseline[i]})"
        elif spec.baseline is not None:
            name = f"({name.removeprefix('configuration ')}) minus {other}"
        else:
            name = f"configuration {key} minus {other}"
    return terms, name


def _holds(spec: ExpectationSpec, low: float, high: float, ref: float) -> bool:
    if not (math.isfinite(low) and math.isfinite(high)):
        return False
    r = spec.relation
    if r == "greater":
        return low > ref
    if r == "less":
        return high < ref
    if r == "equal":
        tol = spec.tolerance or 0.0
        return ref - tol <= low and high <= ref + tol
    lo, hi = spec.interval or (math.nan, math.nan)
    return lo <= low and high <= hi


def _criterion(spec: ExpectationSpec, unit: str) -> str:
    r = spec.relation
    if r == "inside" and spec.interval is not None:
        return f" (must lie inside [{spec.interval[0]:g}, {spec.interval[1]:g}] {unit})"
    if r == "equal":
        target = "zero" if spec.than is not None else f"{spec.value:g} {unit}"
        return f" (must lie within {spec.tolerance:g} {unit} of {target})"
    side = "above" if r == "greater" else "below"
    target = "zero" if spec.than is not None else f"{spec.value:g} {unit}"
    return f" (must lie wholly {side} {target})"
