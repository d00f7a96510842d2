"""How many trials per configuration each declared expectation needs (`run-protocol --plan FILE --power`).

The smallest count with which the report's own test of each expectation (report/evaluate.py) decides it
with 80 % power (`analysis.power`), at the most stringent level of the report's Holm adjustment, alpha / m;
the spread and effect come from a previous SESSION or an assumed CV. docs/protocol.md "Trials needed"
says what a count rests on and when a statement cannot be planned.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .analysis.power import MOST_TRIALS, POWER_TARGET, Equivalence, OneSided, Part, trials_needed
from .analysis.statistics import ALPHA, TInterval, t_interval
from .errors import InvalidInput
from .protocol.expectations import ExpectationSpec, Terms, statements
from .protocol.loaded import LoadedProtocol
from .protocol.plan_steps import Plan, TrialStep
from .report.headline import LABELS, UNITS, trial_values
from .report.model import ReportData

#: The relative effect of a difference statement planned with a coefficient of variation alone.
DEFAULT_EFFECT_RATIO = 0.05


@dataclass(frozen=True)
class Spread:
    """Where the between-trial spread comes from: a previous session's data, or an assumed CV."""

    data: ReportData | None = None
    cv: float | None = None
    effect_ratio: float | None = None  # a difference statement's effect as a fraction of the level

    def describe(self) -> str:
        if self.data is not None:
            s = self.data.session
            how = (
                f"a difference statement's effect is {self.effect_ratio:.3g} of its configurations' mean level "
                "(--power-effect)"
                if self.effect_ratio is not None
                else "a difference statement's effect is the difference SESSION shows"
            )
            return (
                f"between-trial spread: the SD of each configuration's trial values in {s.archive_path} "
                f"({s.mode}, seed {s.seed}); {how}"
            )
        return (
            f"between-trial spread: a coefficient of variation of {self.cv:.3g} in every configuration "
            f"(--power-cv), the SD of each configuration {self.cv:.3g} times a level common to those compared; "
            f"a difference statement's effect is {self.ratio:.3g} of that level (--power-effect)"
        )

    @property
    def ratio(self) -> float:
        return self.effect_ratio if self.effect_ratio is not None else DEFAULT_EFFECT_RATIO


@dataclass(frozen=True)
class PlannedExpectation:
    """One expectation's trial count: `needed` is None when it cannot be planned (`problem` says why) or
    needs more than `MOST_TRIALS` trials per configuration."""

    spec: ExpectationSpec
    test: str
    basis: str
    needed: int | None
    planned: int
    problem: str = ""

    @property
    def decides(self) -> bool:
        """True when the planned trials reach the needed count in every configuration involved."""
        return self.needed is not None and self.planned >= self.needed


@dataclass(frozen=True)
class PowerPlan:
    """Every declared expectation's trial count, at level `alpha_each` per one-sided test."""

    protocol_name: str
    spread: Spread
    alpha_each: float
    expectations: tuple[PlannedExpectation, ...]

    def text(self) -> str:
        m = len(self.expectations)
        lines = [
            f"Trials per configuration for {POWER_TARGET * 100:.0f} % power, {self.protocol_name} "
            f"({m} expectation{'s' if m != 1 else ''}):",
            f"  each test at alpha/m = {ALPHA:g}/{m} = {self.alpha_each:.3g}: the report adjusts the {m} "
            f"expectations' p-values by Holm's method, whose most stringent step compares the smallest with "
            f"alpha/m; a count planned at that level keeps its power whatever the others' p-values",
            f"  {self.spread.describe()}",
            "  a statement of several parts needs every part: its power is at least 1 - the sum of the "
            "parts' misses; an equivalence's (TOST) power is a lower bound too (analysis/power.py)",
            "",
        ]
        width = max((len(p.spec.id) for p in self.expectations), default=11)
        lines.append(f"{'expectation':<{width}}  needed  planned  outcome         test: basis")
        for p in self.expectations:
            outcome = "decides" if p.decides else "cannot plan" if p.problem else "CANNOT DECIDE"
            needed = str(p.needed) if p.needed is not None else "-" if p.problem else f">{MOST_TRIALS}"
            basis = p.problem or p.basis
            lines.append(
                f"{p.spec.id:<{width}}  {needed:>6}  {p.planned:>7}  {outcome:<14}  {p.test}: {basis}"
            )
        short = [p.spec.id for p in self.expectations if not p.decides and not p.problem]
        unplanned = [p.spec.id for p in self.expectations if p.problem]
        lines.append("")
        if short:
            lines.append(
                f"The planned trials cannot decide {len(short)} of {m} expectations at {POWER_TARGET * 100:.0f} % power "
                f"(planned below needed): {', '.join(short)}."
            )
        else:
            lines.append(
                "The planned trials reach the needed count of every expectation that could be planned."
            )
        if unplanned:
            lines.append(f"Not planned ({len(unplanned)}): {', '.join(unplanned)} (see the reasons above).")
        return "\n".join(lines)


def check_session(data: ReportData, loaded: LoadedProtocol, shown: Path) -> str:
    """A refusal (`InvalidInput`) when SESSION is an archive of another protocol; a warning ("" if none)
    when it was made with another version of this protocol's file."""
    name = data.session.protocol_name
    if name != loaded.protocol.name:
        raise InvalidInput(
            f"--power {shown}: an archive of protocol {name!r}, not of {loaded.protocol.name!r}: the spread "
            "of another campaign's configurations says nothing of this one's; give a session of this protocol"
        )
    if data.session.protocol_sha256 != loaded.sha256:
        return (
            f"run-protocol: warning: --power {shown} was made with another version of {loaded.protocol.name}'s "
            "file (its sha256 differs): its configurations are read by key"
        )
    return ""


def plan_power(loaded: LoadedProtocol, plan: Plan, spread: Spread) -> PowerPlan:
    """The trial count of every expectation `loaded` declares (module docstring)."""
    specs = loaded.protocol.expectations
    alpha_each = ALPHA / max(1, len(specs))
    planned: dict[int, int] = {}
    for step in plan.steps:
        if isinstance(step, TrialStep) and step.brace == "on":
            planned[step.configuration] = planned.get(step.configuration, 0) + 1
    return PowerPlan(
        loaded.protocol.name,
        spread,
        alpha_each,
        tuple(_plan_one(spec, spread, alpha_each, planned) for spec in specs),
    )


def _test_name(spec: ExpectationSpec) -> str:
    r = spec.relation
    two_groups = r in ("increasing", "decreasing", "no_trend") or spec.than is not None or spec.baseline
    kind = "Welch" if two_groups else "one-sample t"
    if r in ("equal", "no_trend", "inside"):
        return f"TOST ({kind})"
    return f"one-sided {kind}"


def _fmt(value: float) -> str:
    return f"{value:.3g}"


class _CannotPlan(Exception):
    """Why a statement's count cannot be computed."""


def _plan_one(
    spec: ExpectationSpec, spread: Spread, alpha_each: float, planned: dict[int, int]
) -> PlannedExpectation:
    keys = spec.named_keys
    n_planned = min(planned.get(k, 0) for k in keys)
    test = _test_name(spec)
    try:
        stats = _session_stats(spec, spread.data, keys) if spread.data is not None else {}
        parts = [(name, *_part(spec, terms, name, spread, stats)) for terms, name in statements(spec)]
    except _CannotPlan as why:
        return PlannedExpectation(spec, test, "", None, n_planned, str(why))
    needed = trials_needed([part for _, part, _ in parts], alpha_each, least=spec.min_trials)
    # the parts' bases: "a: x; b: y", or "a, b: each x" when every part rests on the same
    texts = {basis for _, _, basis in parts}
    if len(parts) > 1 and len(texts) == 1:
        basis = f"{', '.join(name for name, _, _ in parts)}: each {texts.pop()}"
    else:
        basis = "; ".join(f"{name}: {text}" for name, _, text in parts)
    return PlannedExpectation(spec, test, basis, needed, n_planned)


def _session_stats(spec: ExpectationSpec, data: ReportData, keys: Sequence[int]) -> dict[int, TInterval]:
    label = LABELS[spec.metric]
    out: dict[int, TInterval] = {}
    for key in keys:
        cfg = data.configuration(key)
        if cfg is None:
            raise _CannotPlan(f"SESSION has no configuration {key}")
        values = trial_values(cfg, spec.metric, percentile=spec.percentile, angle_deg=spec.angle_deg)
        interval = t_interval(values)
        if interval.n < 2 or not math.isfinite(interval.sd):
            raise _CannotPlan(
                f"SESSION has {interval.n or 'no'} trial{'' if interval.n == 1 else 's'} of configuration {key} "
                f"with {label}: no between-trial spread to plan from"
            )
        out[key] = interval
    return out


def _part(
    spec: ExpectationSpec, terms: Terms, name: str, spread: Spread, stats: dict[int, TInterval]
) -> tuple[Part, str]:
    """One part's test and the text of what it rests on."""
    unit = UNITS[spec.metric]
    r = spec.relation
    if spread.data is None:
        return _part_from_cv(spec, terms, name, spread.cv or math.nan, spread.ratio)
    sd_terms = tuple(abs(w) * stats[k].sd for w, k in terms)
    observed = sum(w * stats[k].mean for w, k in terms)
    sds = "SD " + ", ".join(_fmt(stats[k].sd) for _, k in terms) + f" {unit}"
    if r in ("equal", "no_trend"):
        margin = spec.margin or 0.0
        ref = spec.value if (r == "equal" and spec.value is not None) else 0.0
        part: Part = Equivalence(ref, ref - margin, ref + margin, sd_terms)
        return part, f"within ±{margin:g} {unit}, true difference 0; {sds}"
    if r == "inside" and spec.interval is not None:
        low, high = spec.interval
        if not low < observed < high:
            raise _CannotPlan(
                f"{name} is {_fmt(observed)} {unit} in SESSION, outside [{low:g}, {high:g}]: "
                "a count is planned for a true statement"
            )
        return (
            Equivalence(observed, low, high, sd_terms),
            f"{_fmt(observed)} {unit} in SESSION, inside [{low:g}, {high:g}]; {sds}",
        )
    sign = -1.0 if r in ("less", "decreasing") else 1.0
    way = "below" if sign < 0 else "above"
    if spec.value is not None:
        effect = sign * (observed - spec.value)
        basis = f"{_fmt(observed)} {unit} in SESSION, {_fmt(effect)} {way} {spec.value:g}"
    elif spread.effect_ratio is not None:
        level = sum(abs(stats[k].mean) for _, k in terms) / len(terms)
        effect = spread.effect_ratio * level
        basis = f"{way} 0 by {spread.effect_ratio:.3g} × {_fmt(level)} = {_fmt(effect)} {unit}"
    else:
        effect = sign * observed
        basis = f"{_fmt(observed)} {unit} in SESSION"
    if not effect > 0.0:
        reference = f"{spec.value:g} {unit}" if spec.value is not None else "0"
        why = (
            "no distance to plan for"
            if spec.value is not None
            else "no effect in the stated direction to plan for (give --power-effect FRACTION to plan for an "
            "effect of that size)"
        )
        raise _CannotPlan(f"{name} is {_fmt(observed)} {unit} in SESSION, not {way} {reference}: {why}")
    return OneSided(effect, sd_terms), f"{basis}; {sds}"


def _part_from_cv(
    spec: ExpectationSpec, terms: Terms, name: str, cv: float, ratio: float
) -> tuple[Part, str]:
    """A part with every configuration's SD `cv` times a common level (no session: no means)."""
    unit = UNITS[spec.metric]
    r = spec.relation
    single = len(terms) == 1
    if r in ("equal", "no_trend", "inside"):
        if not single:
            lo, hi = spec.interval or (math.nan, math.nan)
            what = (
                f"the margin ±{spec.margin:g} {unit}"
                if r != "inside"
                else f"the interval [{lo:g}, {hi:g}] {unit}"
            )
            raise _CannotPlan(
                f"{what} is in the metric's unit, and a CV gives no level to scale the SDs by: plan with "
                "--power SESSION"
            )
        if r == "inside" and spec.interval is not None:
            low, high = spec.interval
            centre = (low + high) / 2.0
        else:
            centre = spec.value or 0.0
            low, high = centre - (spec.margin or 0.0), centre + (spec.margin or 0.0)
        if centre == 0.0:
            raise _CannotPlan(
                "the statement's centre is 0: a CV gives no SD there; plan with --power SESSION"
            )
        sd = cv * abs(centre)
        return (
            Equivalence(centre, low, high, (sd,)),
            f"assumed at {_fmt(centre)} {unit}, inside [{_fmt(low)}, {_fmt(high)}]; SD {_fmt(sd)} {unit}",
        )
    way = "below" if r in ("less", "decreasing") else "above"
    reference = f"{spec.value:g} {unit}" if spec.value is not None else "0"
    return (
        OneSided(ratio, tuple(abs(w) * cv for w, _ in terms)),
        f"{way} {reference} by {ratio:.3g} of a common level, its SD {cv:.3g} of it",
    )
