"""The sampler the output loop feeds (`Rig.tap`): decimated angle and torque for the live traces.

At every scan read (every 10 output ticks, 100 ms at 100 Hz) the rig hands the block it just read to
`SampleTap.scan`. The tap keeps one row every 1/`SAMPLE_RATE_HZ` seconds of scan time (2 rows of the 100
a read brings at 1 kHz), converts only those rows (Eq 2/3 and the look-up tables, as the recording will
be), pairs them with the angle commanded at that moment, and queues one `samples` message on the bus.
That is a few numpy operations on 2-element arrays and one deque append per read: about 20 µs every
100 ms, inside the slack before the next tick. Anything unexpected disables the tap; it never raises into
the loop.

Times are the rig clock's seconds (continuous over approach, run and park, and from step to step); in a
dry run in simulated time they advance in bursts far faster than the wall clock, with `--realtime` at the
rig's pace.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ..hardware.interfaces import ScanBlock
    from ..hardware.joint import JointConfig

SAMPLE_RATE_HZ = 20.0
"""Points per second of scan time sent to the page (the issue asks for about 20 Hz)."""


def phase_of(where: str) -> str:
    """What a paced run is, from the label the steps give it: "approach", "park" or "run"."""
    if "(approach)" in where:
        return "approach"
    if "(park)" in where or where.startswith("park"):
        return "park"
    return "run"


class SampleTap:
    """A `hardware.interfaces.LoopTap` that publishes decimated samples of one joint."""

    def __init__(
        self,
        joint: JointConfig,
        sink: Callable[[dict[str, Any]], None],
        *,
        rate_hz: float = SAMPLE_RATE_HZ,
    ) -> None:
        self.joint = joint
        self.sink = sink
        self.step = ""  # the current step's id (set by the publisher at each step start)
        self.enabled = True
        self.error = ""
        self._period = 1.0 / rate_hz
        self._in_rate = float(joint.input_rate_hz)
        self._out_rate = float(joint.output_rate_hz)
        self._stride = max(1, round(self._in_rate / rate_hz))
        self._cmd: npt.NDArray[np.float64] = np.zeros(1)
        self._t0 = 0.0
        self._next = -math.inf
        self._where = ""
        self._phase = "run"

    def start(self, where: str, command_deg: npt.NDArray[np.float64], t0_s: float) -> None:
        self._cmd = command_deg if command_deg.shape[0] else np.zeros(1)
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
        angle = self.joint.angle_from_volts(volts[:, 0])
        torque = self.joint.torque_from_volts(volts[:, 1])
        tick = ((ts - self._t0) * self._out_rate).astype(np.int64)
        np.clip(tick, 0, self._cmd.shape[0] - 1, out=tick)
        points = np.round(np.column_stack((ts, self._cmd[tick], angle, torque)), 3)
        self._next = float(ts[-1]) + self._period
        self.sink(
            {
                "type": "samples",
                "step": self.step,
                "joint": self.joint.name,
                "where": self._where,
                "phase": self._phase,
                "points": points.tolist(),
            }
        )
