"""The session's side of the monitor: hook calls turned into bus messages.

`LivePublisher` implements `publisher.Publisher` (step start and end, progress and ETA over the whole
campaign, calibration verdicts) and feeds the rig's `SampleTap`s the current step. `MonitoredOperator`
wraps a person's prompts so the page shows a banner while the session waits for the operator.
`SampleTap`, the sampler the output loop feeds (`Rig.tap`), sends decimated angle and torque of every
driven joint for the live traces, converted as the recording will be; anything unexpected disables the
tap: it never raises into the loop.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import numpy.typing as npt

from ..protocol.plan_steps import ChecklistStep, Plan, Step, TrialStep
from ..session.progress import describe
from .bus import EventBus

T = TypeVar("T")

if TYPE_CHECKING:
    from ..hardware.interfaces import ScanBlock
    from ..hardware.joint import JointConfig
    from ..steps.operator import Answer, Operator

SAMPLE_RATE_HZ = 20.0
"""Points per second of scan time sent to the page: smooth live traces at a few bytes per point."""


def phase_of(where: str) -> str:
    """What a paced run is, from the label the steps give it: "approach", "park" or "run"."""
    if "(approach)" in where:
        return "approach"
    if "(park)" in where or where.startswith("park"):
        return "park"
    return "run"


class SampleTap:
    """A `hardware.interfaces.LoopTap`: one `samples` message per driven joint and scan read.

    `joints` in the rig's command column order; `scan_channels` the scan's channels in column order (by
    default [angle, torque] of each joint in turn). A block without a joint's columns gives no samples of
    that joint; commands of the first joint alone (ticks, not ticks x joints) leave the others' null."""

    def __init__(
        self,
        joints: Sequence[JointConfig],
        sink: Callable[[dict[str, Any]], None],
        *,
        scan_channels: Sequence[int] | None = None,
    ) -> None:
        if not joints:
            raise ValueError("a sample tap needs at least one joint")
        self.joints = tuple(joints)
        self.sink = sink
        self.step = ""  # the current step's id (set by the publisher at each step start)
        self.enabled = True
        self.error = ""
        channels = list(
            scan_channels
            if scan_channels is not None
            else [ch for j in self.joints for ch in (j.angle_input_channel, j.torque_input_channel)]
        )
        # per joint: (its angle column, its torque column) in the scan
        self._columns = [
            (channels.index(j.angle_input_channel), channels.index(j.torque_input_channel))
            for j in self.joints
        ]
        first = self.joints[0]
        self._period = 1.0 / SAMPLE_RATE_HZ
        self._in_rate = float(first.input_rate_hz)
        self._out_rate = float(first.output_rate_hz)
        self._stride = max(1, round(self._in_rate / SAMPLE_RATE_HZ))
        self._cmd: npt.NDArray[np.float64] = np.zeros((1, 1))
        self._t0 = 0.0
        self._next = -math.inf
        self._where = ""
        self._phase = "run"

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    def start(self, where: str, command_deg: npt.NDArray[np.float64], t0_s: float) -> None:
        cmd = command_deg.reshape(command_deg.shape[0], -1)  # ticks x (joints, or the first joint)
        self._cmd = cmd if cmd.shape[0] else np.zeros((1, cmd.shape[1]))
        self._t0 = t0_s
        self._next = -math.inf
        self._where = where
        self._phase = phase_of(where)

    def scan(self, block: ScanBlock) -> None:
        if not self.enabled:
            return
        try:
            self._scan(block)
        except Exception as exc:  # the loop must go on: stop sampling, keep the reason for /status
            self.enabled = False
            self.error = f"sampling stopped: {exc!r}"

    def _scan(self, block: ScanBlock) -> None:
        t = block.t_s
        n = t.shape[0]
        if n == 0:
            return
        first = float(t[0])
        i = 0 if self._next <= first else math.ceil((self._next - first) * self._in_rate - 1e-6)
        if i >= n:
            return
        ts = t[i :: self._stride]
        volts = block.volts[i :: self._stride]
        if volts.ndim != 2 or volts.shape[1] < 2:
            raise ValueError(f"a scan block of {volts.shape[1] if volts.ndim == 2 else 0} column(s)")
        tick = ((ts - self._t0) * self._out_rate).astype(np.int64)
        np.clip(tick, 0, self._cmd.shape[0] - 1, out=tick)
        self._next = float(ts[-1]) + self._period
        for k, (joint, (a, q)) in enumerate(zip(self.joints, self._columns, strict=True)):
            if max(a, q) >= volts.shape[1]:
                continue  # the loop shows no column of this joint
            angle = joint.angle_from_volts(volts[:, a])
            torque = joint.torque_from_volts(volts[:, q])
            cmd = self._cmd[tick, k] if k < self._cmd.shape[1] else np.full(ts.shape[0], np.nan)
            points = np.round(np.column_stack((ts, cmd, angle, torque)), 3)
            self.sink(
                {
                    "type": "samples",
                    "step": self.step,
                    "joint": joint.name,
                    "where": self._where,
                    "phase": self._phase,
                    "points": points.tolist(),
                }
            )


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
        ask = functools.partial(self.inner.checklist, step)
        return self._ask("checklist", step.title, ask, step=step.id, items=list(step.items))

    def accept_failed_check(self, message: str) -> bool:
        return self._ask("failed_check", message, lambda: self.inner.accept_failed_check(message))
