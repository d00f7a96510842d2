"""The session's side of the monitor: hook calls turned into bus messages.

`LivePublisher` implements `publisher.Publisher` (step start and end, progress and ETA over the whole
campaign, calibration verdicts) and feeds the rig's `SampleTap`s the current step. `MonitoredOperator`
wraps a person's prompts so the page shows a banner while the session waits for the operator.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

from ..protocol.plan_steps import ChecklistStep, Plan, Step, TrialStep
from ..session.progress import describe
from .bus import EventBus
from .samples import SampleTap

T = TypeVar("T")

if TYPE_CHECKING:
    from ..steps.operator import Answer, Operator


def step_fields(step: Step) -> dict[str, Any]:
    """Set, configuration, trial, brace and the like: what the page shows of a step."""
    out: dict[str, Any] = {"step": step.id, "kind": step.kind, "describe": describe(step)}
    for name in ("set", "configuration", "trial", "brace", "when", "title"):
        value = getattr(step, name, None)
        if value is not None:
            out[name] = value
    if isinstance(step, ChecklistStep):
        out["items"] = list(step.items)
    if isinstance(step, TrialStep) and step.twin is not None:
        out["derived_from"] = step.twin
    return out


class LivePublisher:
    def __init__(self, bus: EventBus) -> None:
        self.bus = bus
        self.taps: list[SampleTap] = []
        self._plan: Plan | None = None
        self._index: dict[str, int] = {}
        self._done: set[str] = set()
        self._robot_total = 0.0
        self._robot_done = 0.0
        self._t0 = time.monotonic()

    # ------------------------------------------------------------------------------ Publisher

    def begin(self, plan: Plan, done: Collection[str]) -> None:
        self._plan = plan
        self._index = {s.id: i for i, s in enumerate(plan.steps)}
        self._done = {d for d in done if d in self._index}
        self._robot_total = sum(s.robot_time_s for s in plan.steps if s.id not in self._done)
        self._robot_done = 0.0
        self._t0 = time.monotonic()
        self.bus.publish(self._progress())

    def step_start(self, step: Step) -> None:
        for tap in self.taps:
            tap.step = step.id
        msg = {"type": "step_start", **step_fields(step), "robot_time_s": step.robot_time_s}
        if step.id in self._index:
            msg["index"] = self._index[step.id] + 1
            msg["total"] = len(self._index)
        msg["next_action"] = self._next_action(step)
        self.bus.publish(msg)

    def step_end(self, step: Step, summary: str) -> None:
        if step.id in self._index and step.id not in self._done:
            self._done.add(step.id)
            self._robot_done += step.robot_time_s
        self.bus.publish({"type": "step_end", "step": step.id, "kind": step.kind, "summary": summary})
        self.bus.publish(self._progress())

    def verdict(self, step_id: str, verdict: str, detail: Mapping[str, object]) -> None:
        self.bus.publish({"type": "verdict", "step": step_id, "verdict": verdict, **detail})

    # --------------------------------------------------------------------------------- helpers

    def _progress(self) -> dict[str, Any]:
        elapsed = time.monotonic() - self._t0
        remaining = max(0.0, self._robot_total - self._robot_done)
        eta = elapsed / self._robot_done * remaining if self._robot_done > 0 else None
        return {
            "type": "progress",
            "done": len(self._done),
            "total": len(self._index),
            "robot_s_total": round(self._robot_total, 1),
            "robot_s_done": round(self._robot_done, 1),
            "robot_s_remaining": round(remaining, 1),
            "elapsed_s": round(elapsed, 1),
            "eta_s": None if eta is None else round(eta, 1),
        }

    def _next_action(self, step: Step) -> dict[str, Any] | None:
        """The next checklist after `step`: what the operator will be asked to do, and how soon."""
        if self._plan is None or step.id not in self._index:
            return None
        steps = self._plan.steps
        i = self._index[step.id]
        for j in range(i + 1, len(steps)):
            nxt = steps[j]
            if isinstance(nxt, ChecklistStep) and nxt.id not in self._done:
                return {
                    "step": nxt.id,
                    "title": nxt.title,
                    "items": list(nxt.items),
                    "brace": nxt.brace,
                    "steps_away": j - i,
                    "robot_s_until": round(sum(s.robot_time_s for s in steps[i:j]), 1),
                }
        return None


class MonitoredOperator:
    """A person's prompts, with an `operator_wait` banner on the page while they are open."""

    def __init__(self, inner: Operator, bus: EventBus) -> None:
        self.inner = inner
        self.bus = bus

    def _ask(self, kind: str, prompt: str, ask: Callable[[], T], **extra: Any) -> T:
        """`ask()` the person with the `operator_wait` banner up, taken down however the prompt ends."""
        self.bus.publish({"type": "operator_wait", "waiting": True, "kind": kind, "prompt": prompt, **extra})
        try:
            return ask()
        finally:
            self.bus.publish({"type": "operator_wait", "waiting": False})

    def checklist(self, step: ChecklistStep) -> Answer:
        items = list(step.items)
        return self._ask(
            "checklist", step.title, lambda: self.inner.checklist(step), step=step.id, items=items
        )

    def accept_failed_check(self, message: str) -> bool:
        return self._ask("failed_check", message, lambda: self.inner.accept_failed_check(message))
