"""The sampler the output loop feeds (`Rig.tap`): decimated angle and torque of every driven joint for the
live traces, converted as the recording will be (docs/monitor.md). Anything unexpected disables the tap;
it never raises into the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ..hardware.interfaces import ScanBlock
    from ..hardware.joint import JointConfig

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
