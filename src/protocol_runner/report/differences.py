"""Within-report statistics that involve several configurations, the trial as the unit.

- Differences: for each declared comparison, the energy per cycle of each configuration minus the one
  before it in the comparison's declared order (adjacent differences), with the 95 % Welch interval on
  trial means (`analysis.statistics.welch_interval`).
- Repeatability: for each group the protocol declares in `report.repeatability` (configurations with
  identical settings run in different sets, checked by `--validate`), the between-set coefficient of
  variation of the configurations' means and the one-way random-effects ICC(1) of their trial means
  (`analysis.statistics.repeatability`).

Public API: adjacent_differences(data, comparison), declared_repeatability(data)
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

from protocol_runner.analysis.statistics import Repeatability, WelchInterval, welch_interval
from protocol_runner.protocol.expectations import RepeatabilitySpec
from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.declared import declared_entries
from protocol_runner.report.headline import group_repeatability
from protocol_runner.report.metrics import trial_values
from protocol_runner.report.model import ReportData


@dataclass(frozen=True)
class Difference:
    """Energy per cycle of configuration `key` minus configuration `base` (J), trial means."""

    base: int
    key: int
    energy: WelchInterval
    trials: tuple[int, int]  # trials of base, of key


def adjacent_differences(data: ReportData, comparison: Comparison) -> tuple[Difference, ...]:
    """Each present configuration of `comparison` minus the present one before it, in declared order."""
    present = [k for k in comparison.configurations if data.configuration(k) is not None]
    out = []
    for base, key in pairwise(dict.fromkeys(present)):
        cb, ck = data.configuration(base), data.configuration(key)
        assert cb is not None and ck is not None  # filtered above
        a, b = trial_values(cb, "energy_per_cycle"), trial_values(ck, "energy_per_cycle")
        out.append(Difference(base, key, welch_interval(a, b), (len(a), len(b))))
    return tuple(out)


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
        groups.append(RepeatabilityGroup(spec, present, missing, group_repeatability(data, present)))
    return tuple(groups), problems
