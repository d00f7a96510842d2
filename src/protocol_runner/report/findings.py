"""The campaign's declared expectations, evaluated on an archive's data for the report.

The statements come from the protocol as archived (`/protocol`, its `expectations:` list, docs/protocol.md
"Expectations"); the generic evaluator `protocol_runner.report.evaluate` decides each one. Nothing
here knows any campaign: no configuration key, factor level or threshold.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.report.declared import declared_entries
from protocol_runner.report.evaluate import Verdict, evaluate_all
from protocol_runner.report.model import ReportData

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


def declared_expectations(protocol_text: str) -> tuple[tuple[ExpectationSpec, ...], tuple[str, ...]]:
    """The `expectations:` of an archived protocol text, and a message per entry that is not valid."""
    return declared_entries(protocol_text, ("expectations",), ExpectationSpec)


def evaluate_expectations(data: ReportData) -> Expectations:
    """Every declared expectation of `data`'s archived protocol, decided on `data`: once per `data` object
    (the session's recorded verdicts and its report, rendered next, decide them on the same one; the data
    are frozen, so the verdicts are the same)."""
    for seen, result in _LAST:
        if seen() is data:
            return result
    specs, problems = declared_expectations(data.protocol_text)
    result = Expectations(evaluate_all(specs, data), problems, data.session.mode == "dry-run")
    _LAST[:] = [(weakref.ref(data), result)]
    return result


_LAST: list[tuple[weakref.ref[ReportData], Expectations]] = []
