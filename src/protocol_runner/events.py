"""What the runner and the steps tell the live monitor, and the do-nothing version used without one.

The session code calls these few methods at step boundaries only (never inside the output loop; the
loop's own samples go through `hardware.interfaces.LoopTap`). Without `--monitor` the runner holds
`NULL_PUBLISHER`, whose methods return at once.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from .protocol.plan_steps import Plan, Step


class Publisher(Protocol):
    """Session happenings, published to the live monitor; every method returns at once (never blocks)."""

    def begin(self, plan: Plan, done: Collection[str]) -> None:
        """The runner starts (or resumes) `plan`; `done` are the step ids already complete."""
        ...

    def step_start(self, step: Step) -> None: ...

    def step_end(self, step: Step, summary: str) -> None: ...

    def verdict(self, step_id: str, verdict: str, detail: Mapping[str, object]) -> None:
        """A calibration check's verdict ("pass", "accepted", "fail") and its figures."""
        ...


class NullPublisher:
    """No monitor: every call does nothing."""

    def begin(self, plan: Plan, done: Collection[str]) -> None: ...

    def step_start(self, step: Step) -> None: ...

    def step_end(self, step: Step, summary: str) -> None: ...

    def verdict(self, step_id: str, verdict: str, detail: Mapping[str, object]) -> None: ...


NULL_PUBLISHER = NullPublisher()
