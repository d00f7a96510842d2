"""One generic evaluator: a declared expectation and an archive's data give a verdict with its numbers.

The decision rules are docs/protocol.md "Expectations" (tests on trial values, the experimental unit, at
level `ALPHA`; one Holm family). Nothing here knows any campaign's configuration key, factor level or
threshold. `record_verdicts` stores the verdicts in the archive (`/expectations`, docs/archive.md),
decided by the very code the report re-runs, so a stored verdict never disagrees with a regenerated report.
"""

from __future__ import annotations

import dataclasses
import json
import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import h5py
import numpy as np

from protocol_runner.analysis.statistics import (
    ALPHA,
    TInterval,
    WelchInterval,
    contrast_interval,
    holm,
    p_above,
    p_below,
    t_interval,
)
from protocol_runner.archive.h5util import put_attrs, put_text
from protocol_runner.archive.paths import JOINTS
from protocol_runner.protocol.expectations import ExpectationSpec, statements
from protocol_runner.protocol.only import key_spans
from protocol_runner.protocol.wording import counted
from protocol_runner.report.declared import declared_entries
from protocol_runner.report.headline import LABELS, UNITS, trial_values
from protocol_runner.report.model import Configuration, ReportData
from protocol_runner.report.settings_view import DeviceElement

MET, NOT_MET, NOT_EVALUABLE = "met", "not met", "not evaluable"

#: Confidence of the interval printed beside a one-sided or equivalence test at level ALPHA.
TEST_CONFIDENCE = 1.0 - 2.0 * ALPHA


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
    """The outcome of one expectation, with the numbers that decided it.

    `p_value` is the expectation's own test; `p_adjusted` is Holm's over the `family` evaluable
    expectations it was decided with (NaN when not evaluable)."""

    spec: ExpectationSpec
    verdict: str
    reason: str
    evidence: tuple[Evidence, ...]
    p_value: float = math.nan
    p_adjusted: float = math.nan
    family: int = 0
    joint: str = ""  # the joint whose data decided it ("" when the archive says none)

    @property
    def unit(self) -> str:
        """The metric's unit."""
        return UNITS[self.spec.metric]


def _fmt(value: float) -> str:
    return f"{value:.3g}" if abs(value) < 1 else f"{value:.2f}" if abs(value) < 100 else f"{value:.1f}"


def format_p(p: float) -> str:
    """A p-value as the report prints it: "< 0.001", three significant digits, "—" when undefined."""
    if not math.isfinite(p):
        return "—"
    return "< 0.001" if p < 0.001 else f"{p:.3g}"


def metric_label(spec: ExpectationSpec) -> str:
    """Readable metric name with its argument, e.g. "angle percentile 99"."""
    label = LABELS[spec.metric]
    if spec.metric == "angle_percentile":
        return f"{label} {spec.percentile:g}"
    if spec.metric == "hysteresis_width":
        return f"{label} at {spec.angle_deg:g}°"
    return label


def joints_of(spec: ExpectationSpec, data: ReportData) -> tuple[str, ...]:
    """The joints `spec` is decided for, one verdict each: its `joint`, every joint of the archive for
    `joints: all`, else the archive's joints when it has one ("" when it names several: not evaluable)."""
    if spec.joint is not None:
        return (spec.joint,)
    if spec.joints == "all":
        return _joints(data) or ("",)
    return _joints(data) if len(_joints(data)) == 1 else ("",)


def _joints(data: ReportData) -> tuple[str, ...]:
    """The archive's joints in channel order (of data built without them, its configurations')."""
    return data.joints or tuple(dict.fromkeys(c.joint for c in data.configurations))


def _why_short(data: ReportData, key: int, joint: str, n: int, spec: ExpectationSpec) -> str:
    """Why configuration `key` gave `joint` only `n` trial values of the metric: absent from the archive,
    not run, no data of that joint, no processed trial, or too few trials with the metric."""
    cfg = data.configuration(key, joint)
    if cfg is None:
        if not any(c.key == key for c in data.configurations):
            return f"configuration {key} is not in this archive"
        return f"configuration {key} has no data of joint {joint}"
    if cfg.status == "not run":
        return f"configuration {key} was not run"
    recorded = sum(t.recorded for t in cfg.trials)
    if not n and recorded and not any(t.processed is not None for t in cfg.trials):
        return f"configuration {key} has {counted(recorded, 'recorded trial')}, none processed"
    return f"configuration {key} has {counted(n, 'trial') if n else 'no trials'} with {metric_label(spec)}"


def _tested(spec: ExpectationSpec, data: ReportData, joint: str) -> Verdict:
    """`spec` tested on `joint`'s data of `data`: its p-value and numbers, not yet decided (or `not
    evaluable`)."""
    unit = UNITS[spec.metric]
    keys = spec.named_keys
    if joint not in _joints(data):
        return Verdict(spec, NOT_EVALUABLE, _no_joint(spec, data), (), joint=joint)
    values: dict[int, tuple[float, ...]] = {}
    for key in keys:
        cfg = data.configuration(key, joint)
        values[key] = (
            ()
            if cfg is None
            else trial_values(cfg, spec.metric, percentile=spec.percentile, angle_deg=spec.angle_deg)
        )
    intervals = {key: t_interval(v) for key, v in values.items()}
    evidence = tuple(Evidence(k, i.n, i.mean, i.low, i.high) for k, i in intervals.items())
    short = [k for k in keys if intervals[k].n < spec.min_trials]
    problems: list[str] = []
    if short:
        only = data.session.only
        left_out = [
            k for k in short if only and k not in only and not any(c.key == k for c in data.configurations)
        ]
        parts = [_why_short(data, k, joint, intervals[k].n, spec) for k in short if k not in left_out]
        if left_out:
            many = len(left_out) > 1
            parts.append(
                f"configuration{'s' if many else ''} {', '.join(map(str, left_out))} {'were' if many else 'was'} "
                f"not run (the session ran only {key_spans(only)})"
            )
        problems.append("; ".join(parts) + f" (the rule needs {spec.min_trials} per configuration).")
    unreached = _unreached(spec, data, joint)
    if unreached:
        problems.append(unreached)
    whose = f"joint {joint}: " if len(_joints(data)) > 1 else ""  # which joint's data, when there is a choice
    if problems:
        return Verdict(spec, NOT_EVALUABLE, whose + " ".join(problems), evidence, joint=joint)
    p, reason = _decide(spec, values, intervals, unit)
    p = p if math.isfinite(p) else 1.0  # an undefined test never supports the statement
    return Verdict(spec, NOT_MET, whose + reason, evidence, p, joint=joint)


def _no_joint(spec: ExpectationSpec, data: ReportData) -> str:
    """Why no joint's data can decide `spec`: the joint it names is not in the archive, or it names none
    and the archive holds several."""
    shown = ", ".join(_joints(data)) or "none"
    if spec.joint is not None:
        return f"joint {spec.joint} is not in this archive (its joints: {shown})."
    return (
        f"this archive holds several joints ({shown}) and the expectation names none: "
        "declare `joint: <one of them>` or `joints: all`."
    )


def _adjusted(v: Verdict, p_adjusted: float, family: int) -> Verdict:
    met = p_adjusted <= ALPHA
    how = "a family of one, not adjusted"
    if family > 1:
        how = f"Holm-adjusted over {family} expectations {format_p(p_adjusted)}"
    tail = f"; p {format_p(v.p_value)} ({how}): {MET if met else NOT_MET} at {ALPHA:g}"
    return dataclasses.replace(
        v, verdict=MET if met else NOT_MET, reason=v.reason + tail, p_adjusted=p_adjusted, family=family
    )


def evaluate_all(specs: Sequence[ExpectationSpec], data: ReportData) -> tuple[Verdict, ...]:
    """Every declared expectation's verdicts, in declaration order (one per joint it is decided for, in
    the archive's joint order): the evaluable ones are one family whose p-values are Holm-adjusted; each is
    met when its adjusted p-value is at most `ALPHA`."""
    tested = [_tested(s, data, joint) for s in specs for joint in joints_of(s, data)]
    raw = [v.p_value if v.verdict != NOT_EVALUABLE else math.nan for v in tested]
    family = sum(math.isfinite(p) for p in raw)
    return tuple(
        v if v.verdict == NOT_EVALUABLE else _adjusted(v, p_adj, family)
        for v, p_adj in zip(tested, holm(raw), strict=True)
    )


def _extremes(cfg: Configuration) -> tuple[float, float]:
    """The lowest and highest angle the configuration's brace-on trials reached (deg)."""
    if math.isfinite(cfg.angle_min_deg) and math.isfinite(cfg.angle_max_deg):
        return cfg.angle_min_deg, cfg.angle_max_deg
    angles = [
        t.processed.angle_deg for t in cfg.trials if t.processed is not None and t.processed.angle_deg.size
    ]
    if not angles:
        return math.nan, math.nan
    return min(float(a.min()) for a in angles), max(float(a.max()) for a in angles)


def _unreached(spec: ExpectationSpec, data: ReportData, joint: str) -> str:
    """Why a statement about a device element (`engages`) cannot be decided on `joint`'s data: a
    configuration without the element on that joint, an element without a `range_deg` to reach, or measured
    angles that never reach it ("" when every configuration reaches it)."""
    if spec.engages is None:
        return ""
    end = "either"  # which end of the element's range the statement is about
    if spec.metric == "angle_percentile" and spec.percentile is not None:
        end = "low" if spec.percentile < 50 else "high"
    problems: list[str] = []
    for key in spec.configurations:
        cfg = data.configuration(key, joint)
        if cfg is None:
            continue
        element = _element(cfg, spec.engages, joint)
        if element is None:
            problems.append(f"configuration {key} has no device element {spec.engages!r}")
            continue
        limits = dict(element.params).get("range_deg")
        if not (isinstance(limits, tuple) and len(limits) == 2):
            problems.append(
                f"device element {spec.engages!r} ({element.type}) of configuration {key} has no range_deg "
                "that the measured angle could reach"
            )
            continue
        lo, hi = float(limits[0]), float(limits[1])
        low, high = _extremes(cfg)
        reached_low, reached_high = low <= lo, high >= hi
        reached = {"low": reached_low, "high": reached_high, "either": reached_low or reached_high}[end]
        if not reached:
            problems.append(
                f"configuration {key}'s measured angle spans [{_fmt(low)}, {_fmt(high)}] deg and never reaches "
                f"the {'' if end == 'either' else end + ' '}end of {spec.engages!r} "
                f"([{lo:g}, {hi:g}] deg)"
            )
    if not problems:
        return ""
    return "; ".join(problems) + f": the statement is about {spec.engages!r}, which these data never engage."


def _ordered(keys: Sequence[int], intervals: dict[int, TInterval], unit: str) -> str:
    """The means in the stated order, each pair joined by the comparison the data show."""
    means = [intervals[k].mean for k in keys]
    text = _fmt(means[0])
    for a, b in pairwise(means):
        text += (" < " if a < b else " > " if a > b else " = ") + _fmt(b)
    return f"means in the stated order ({', '.join(str(k) for k in keys)}): {text} {unit}"


def _element(cfg: Configuration, name: str, joint: str) -> DeviceElement | None:
    """The device element `name` that `joint` carries (of a device of one joint, its element `name`)."""
    return next(
        (e for e in cfg.settings.device if e.name == name and dict(e.params).get("joint", joint) == joint),
        None,
    )


def _decide(
    spec: ExpectationSpec, values: dict[int, tuple[float, ...]], intervals: dict[int, TInterval], unit: str
) -> tuple[float, str]:
    """The expectation's p-value (the largest of its statements') and the text of its numbers. The steps of
    `increasing` / `decreasing` are each a one-sided Welch test, the pairs of `no_trend` each a TOST within
    ±margin; the other relations test each configuration (or its contrast) against the stated value."""
    steps = spec.relation in ("increasing", "decreasing", "no_trend")
    parts: list[str] = []
    ps: list[float] = []
    for i, (terms, name) in enumerate(statements(spec)):
        w = contrast_interval([(wt, values[k]) for wt, k in terms], TEST_CONFIDENCE)
        if len(terms) == 1:
            subject = (
                f"configuration {spec.configurations[i]}: mean {_fmt(w.difference)} {unit}, 90 % interval"
            )
        else:
            kind = "Welch" if len(terms) == 2 else "Welch-Satterthwaite"
            name = name if steps or name.startswith("(") else f"configuration {name}"
            subject = f"{name}: {_fmt(w.difference)} {unit}, 90 % {kind} interval"
        ref = 0.0 if steps or spec.than is not None else spec.value or 0.0
        p, test = _statement_p(spec, w, ref)
        ps.append(p)
        fails = "" if p <= ALPHA else " (fails)"
        parts.append(f"{subject} [{_fmt(w.low)}, {_fmt(w.high)}] {unit}, {test} p {format_p(p)}{fails}")
    if not steps:
        return max(ps, default=math.nan), "; ".join(parts) + _criterion(spec, unit)
    if spec.relation == "no_trend":
        rule = f"every pair's 90 % interval must lie inside ±{spec.margin or 0.0:g} {unit}: two one-sided Welch tests"
    else:
        way = "above" if spec.relation == "increasing" else "below"
        rule = f"every step must lie {way} zero, one-sided Welch; the largest step p decides"
    order = list(dict.fromkeys(spec.configurations))
    return max(ps, default=math.nan), f"{_ordered(order, intervals, unit)}; {'; '.join(parts)} ({rule})"


def _statement_p(spec: ExpectationSpec, w: WelchInterval, ref: float) -> tuple[float, str]:
    r = spec.relation
    if r in ("greater", "increasing"):
        return p_above(w, ref), "one-sided"
    if r in ("less", "decreasing"):
        return p_below(w, ref), "one-sided"
    margin = spec.margin or 0.0  # equal, no_trend: within ±margin of ref; inside: within the interval
    lo, hi = spec.interval or (math.nan, math.nan)
    if r in ("equal", "no_trend"):
        lo, hi = ref - margin, ref + margin
    return max(p_above(w, lo), p_below(w, hi)), "TOST"


def _criterion(spec: ExpectationSpec, unit: str) -> str:
    r = spec.relation
    if r == "inside" and spec.interval is not None:
        return f" (the 90 % interval must lie inside [{spec.interval[0]:g}, {spec.interval[1]:g}] {unit})"
    target = "zero" if spec.than is not None else f"{spec.value:g} {unit}"
    if r == "equal":
        return f" (the 90 % interval must lie within ±{spec.margin:g} {unit} of {target}: TOST)"
    side = "above" if r == "greater" else "below"
    return f" (the 90 % interval must lie wholly {side} {target}: one-sided test)"


#: Label shown beside a dry run's verdict that follows from a simulator value chosen to reproduce it.
TUNED_LABEL = "depends on a simulator value chosen to reproduce it"


@dataclass(frozen=True)
class Expectations:
    """The verdicts of every valid declaration, and one message per declaration that could not be read."""

    verdicts: tuple[Verdict, ...]
    problems: tuple[str, ...]
    dry_run: bool

    def tuned(self, verdict: Verdict) -> bool:
        """True when the report must say the verdict depends on a simulator value chosen to reproduce it
        (dry runs only; `simulator_tuned`, `depends_on_simulator` or `tuned` declared)."""
        return self.dry_run and verdict.spec.depends_on_tuning

    def tuned_detail(self, verdict: Verdict) -> str:
        """What the declaration names as chosen: the simulator values, then its `tuned` note ("" if none)."""
        if not self.tuned(verdict):
            return ""
        return "; ".join(
            p for p in (", ".join(verdict.spec.depends_on_simulator), verdict.spec.tuned.strip()) if p
        )


def evaluate_expectations(data: ReportData) -> Expectations:
    """Every declared expectation of `data`'s archived protocol, decided on `data`: once per `data` object
    (the session's recorded verdicts and its report, rendered next, decide them on the same one; the data
    are frozen, so the verdicts are the same)."""
    for seen, result in _LAST:
        if seen() is data:
            return result
    specs, problems = declared_entries(data.protocol_text, ("expectations",), ExpectationSpec)
    result = Expectations(evaluate_all(specs, data), problems, data.session.mode == "dry-run")
    _LAST[:] = [(weakref.ref(data), result)]
    return result


_LAST: list[tuple[weakref.ref[ReportData], Expectations]] = []


def _or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def record_verdicts(archive: Path, data: ReportData | None = None) -> int:
    """Evaluate `archive`'s declared expectations and (re)write `/expectations`; return how many.
    `data` is the archive as `load_report_data` reads it, when the caller has already read it."""
    from protocol_runner.report.load import load_report_data

    result = evaluate_expectations(data if data is not None else load_report_data(Path(archive), workers=1))
    with h5py.File(archive, "a") as h5:
        if "expectations" in h5:
            del h5["expectations"]
        root = h5.create_group("expectations")
        put_attrs(root, "expectations", {"problems": json.dumps(list(result.problems))})
        for v in result.verdicts:
            keyed = (v.spec.joint is not None or v.spec.joints is not None) and bool(v.joint)
            if v.spec.id not in root:
                grp = root.create_group(v.spec.id)
                joints = [w.joint for w in result.verdicts if w.spec.id == v.spec.id]
                put_attrs(grp, "expectation", _declaration(v, result.dry_run, joints if keyed else None))
            grp = root[v.spec.id]
            if keyed:
                grp = grp.require_group(JOINTS).create_group(v.joint)
                put_attrs(grp, "expectation", {"joint": v.joint})
            _outcome(grp, v)
    return len(result.verdicts)


def _declaration(v: Verdict, dry_run: bool, joints: list[str] | None) -> dict[str, object]:
    """The attributes of an expectation's group that its declaration gives (and `joints` when it is
    decided per joint)."""
    return {
        "text": v.spec.text,
        "section": v.spec.section,
        "metric": v.spec.metric,
        "unit": v.unit,
        "relation": v.spec.relation,
        "configurations": json.dumps(v.spec.configurations),
        "declaration": v.spec.model_dump_json(exclude_none=True),
        "simulator_tuned": int(v.spec.depends_on_tuning),  # 0/1: numbers export as doubles
        "depends_on_simulator": json.dumps(v.spec.depends_on_simulator),
        "dry_run": int(dry_run),
        **({JOINTS: np.array(joints, dtype=h5py.string_dtype())} if joints is not None else {}),
    }


def _outcome(grp: h5py.Group, v: Verdict) -> None:
    """The verdict, its numbers and its evidence, in `grp` (the expectation's group or its joint's)."""
    put_attrs(
        grp,
        "expectation",
        {
            "verdict": v.verdict,
            "reason": v.reason,
            **{k: p for k, p in (("p_value", v.p_value), ("p_adjusted", v.p_adjusted)) if math.isfinite(p)},
            "family": v.family,
        },
    )
    rows = [
        {
            "key": e.key,
            "trials": e.n,
            "mean": _or_none(e.mean),
            "ci95_low": _or_none(e.low),
            "ci95_high": _or_none(e.high),
            "unit": v.unit,
        }
        for e in v.evidence
    ]
    put_text(grp, "evidence", json.dumps(rows))
