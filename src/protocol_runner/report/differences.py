"""Within-report statistics over several configurations, the trial as the unit (docs/report.md): the
differences in energy per cycle within each declared comparison (95 % Welch intervals, Holm-adjusted over
the comparison's rows), and the between-set CV and ICC(1) of each declared `report.repeatability` group.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

from protocol_runner.analysis.statistics import (
    ALPHA,
    Repeatability,
    WelchInterval,
    holm,
    repeatability,
    welch_interval,
)
from protocol_runner.protocol.expectations import RepeatabilitySpec
from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.protocol.schema import ComparisonSpec
from protocol_runner.report.declared import declared_entries
from protocol_runner.report.headline import ALL_JOINTS, campaign_stats, trial_values
from protocol_runner.report.model import ReportData


@dataclass(frozen=True)
class Difference:
    """Energy per cycle of configuration `key` minus configuration `base` (J), trial means; `p_adjusted`
    is the Holm-adjusted p-value over the comparison's differences."""

    base: int
    key: int
    energy: WelchInterval
    trials: tuple[int, int]  # trials of base, of key
    p_adjusted: float
    joint: str = ""  # with several joints: the joint, or "all joints" together

    @property
    def label(self) -> str:
        """The subtraction, as the table names it: "13 minus 2"."""
        return f"{self.key} minus {self.base}"

    @property
    def significant(self) -> bool:
        """True when the Holm-adjusted p-value is at most ALPHA (the adjusted interval excludes zero)."""
        return bool(self.p_adjusted <= ALPHA)


def declared_differences(data: ReportData, comparison: Comparison) -> tuple[Difference, ...]:
    """b minus a for each declared pair (a, b) of `comparison` whose configurations are both present, in
    the declared order; without pairs, each present configuration minus the present one before it. With
    several joints, these for each joint in channel order and then for all joints together; the Holm
    adjustment is over every row (one table, one family)."""
    specs, _ = declared_entries(data.protocol_text, ("report", "comparisons"), ComparisonSpec)
    pairs = next((tuple(s.pairs) for s in specs if s.name == comparison.name and s.pairs is not None), None)
    if pairs is None:
        present = [k for k in comparison.configurations if data.configuration(k) is not None]
        pairs = tuple(pairwise(dict.fromkeys(present)))
    rows: list[tuple[int, int, WelchInterval, tuple[int, int], str]] = []
    for joint in data.joints if data.multi_joint else ("",):
        for base, key in pairs:
            a, b = _trial_energies(data, base, joint), _trial_energies(data, key, joint)
            if a is not None and b is not None:
                rows.append((base, key, welch_interval(a, b), (len(a), len(b)), joint))
    if data.multi_joint and data.totals:
        for base, key in pairs:
            ta, tb = campaign_stats(data, base), campaign_stats(data, key)
            if ta is not None and tb is not None:
                a, b = ta.trial_energy_j, tb.trial_energy_j
                rows.append((base, key, welch_interval(a, b), (len(a), len(b)), ALL_JOINTS))
    adjusted = holm([w.p_value for _, _, w, _, _ in rows])
    return tuple(
        Difference(base, key, w, trials, p_adjusted=p, joint=joint)
        for (base, key, w, trials, joint), p in zip(rows, adjusted, strict=True)
    )


def _trial_energies(data: ReportData, key: int, joint: str) -> tuple[float, ...] | None:
    """Joint `joint`'s ("": the only joint's) energy per cycle of each trial of configuration `key`, or None
    when the archive does not hold it."""
    cfg = data.configuration(key, joint or None)
    return None if cfg is None else trial_values(cfg, "energy_per_cycle")


@dataclass(frozen=True)
class RepeatabilityGroup:
    """A declared group's result; `missing` are its keys absent from the archive (e.g. `--only`)."""

    spec: RepeatabilitySpec
    present: tuple[int, ...]
    missing: tuple[int, ...]
    result: Repeatability


def declared_repeatability(data: ReportData) -> tuple[tuple[RepeatabilityGroup, ...], tuple[str, ...]]:
    """Every group of the archived protocol's `report.repeatability`, and a message per unreadable entry."""
    specs, problems = declared_entries(data.protocol_text, ("report", "repeatability"), RepeatabilitySpec)
    groups = []
    for spec in specs:
        keys = tuple(dict.fromkeys(spec.configurations))
        present = tuple(k for k in keys if data.configuration(k) is not None)
        missing = tuple(k for k in keys if k not in present)
        # the trial means of all joints together with several (`campaign_stats`)
        units = [s.trial_energy_j for k in present if (s := campaign_stats(data, k)) is not None]
        groups.append(RepeatabilityGroup(spec, present, missing, repeatability(units)))
    return tuple(groups), problems
