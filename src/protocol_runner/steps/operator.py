"""What a step may ask the operator at the rig: a checklist, or a decision on a failed check (implemented
by `session.operator`; the live monitor wraps it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from ..protocol.plan_steps import ChecklistStep


@dataclass(frozen=True)
class Answer:
    answer: str  # "done"
    answered_utc: str
    automatic: bool


class Operator(Protocol):
    def checklist(self, step: ChecklistStep) -> Answer: ...

    def accept_failed_check(self, message: str) -> bool: ...
