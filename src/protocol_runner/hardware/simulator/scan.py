"""The simulator's DT9814 stand-in: a hardware-paced scan whose reads integrate the simulated robot joints up
to the rows they hand over (`daq._RigModel.acquire`): each joint's model fills its own angle and torque
columns; a scanned channel no joint is wired to carries the first joint's idle-channel noise."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.interfaces import ScanBlock
from protocol_runner.hardware.simulator.output import SimulatedClock, check_channel

FloatArray = npt.NDArray[np.float64]

AI_CHANNELS = 24
"""DT9814-10V: 24 analog inputs (thesis §2.3)."""
AI_MAX_RATE_HZ = 50_000.0
"""DT9814 maximum aggregate rate (thesis §2.3)."""
TRANSFER_S = 1.0
"""In simulated time the board hands its rows over in transfers of this much scan time, as a USB board
hands over whole packets: a read before a transfer is complete returns no rows, `stop_scan` returns the
rest. The rows do not depend on it (the plant is integrated on a fixed grid whatever the reads); it sets
how many compiled calls a dry run makes: one per second of scan instead of one per read of the rig's loop
(every 100 ms). In real time (`--realtime`) every row is handed over as soon as it is due
(`SimulatedAnalogInput.transfer_s` = 0)."""


class RobotModel(Protocol):
    """What the scan reads from: one simulated robot joint (`daq._RigModel`)."""

    @property
    def channels(self) -> tuple[int, int]:
        """Its (angle, torque) input channels."""
        ...

    def acquire(
        self,
        t0_s: float,
        rate_hz: float,
        first_row: int,
        n_rows: int,
        channels: Sequence[int],
        until_s: float,
    ) -> tuple[FloatArray, npt.NDArray[np.int32], FloatArray]: ...


class ScanState:
    """A running hardware-paced scan: its channels, rate, start and rows handed out so far."""

    def __init__(self, channels: tuple[int, ...], rate_hz: float, t0_s: float, transfer_rows: int) -> None:
        self.channels = channels
        self.rate_hz = rate_hz
        self.t0_s = t0_s
        self.transfer_rows = transfer_rows
        self.rows_read = 0
        self.empty = ScanBlock.empty(len(channels))

    def rows_due(self, now_s: float) -> int:
        """Rows acquired by `now_s` and not yet read (row i at t0 + i / rate; the first at t0)."""
        n_due = math.floor((now_s - self.t0_s) * self.rate_hz + 1e-9) + 1
        return max(0, n_due - self.rows_read)

    def row_time_s(self, row: int) -> float:
        """When row `row` was acquired (the plant kernel's arithmetic: t0 + row / rate)."""
        return self.t0_s + row / self.rate_hz


class SimulatedAnalogInput:
    """A DT9814 stand-in: a hardware-paced scan of 12-bit ±10 V two's-complement codes. Reading it
    integrates the simulated robot (lazily) up to the rows it hands over: the complete transfers
    (`transfer_s`; in real time every row) acquired since the last read."""

    def __init__(self, models: Sequence[RobotModel], clock: SimulatedClock) -> None:
        self._models = tuple(models)
        self._clock = clock
        self._channels: tuple[int, ...] = ()
        # per model reading this scan: its channels and their columns
        self._plan: list[tuple[RobotModel, tuple[int, ...], list[int]]] = []
        self._scan: ScanState | None = None
        self.transfer_s = 0.0 if clock.realtime else TRANSFER_S
        """Scan time per transfer, for the scans started from now on (0: every row as soon as it is due)."""

    @property
    def resolution_bits(self) -> int:
        return 12

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        if len(channels) == 0:
            raise InvalidInput("DT9814 (simulated): a scan needs at least one channel")
        chans = tuple(check_channel(c, AI_CHANNELS, "DT9814 (simulated)") for c in channels)
        if not (math.isfinite(rate_hz) and 0.0 < rate_hz * len(chans) <= AI_MAX_RATE_HZ):
            raise InvalidInput(
                f"DT9814 (simulated): scan rate must be > 0 and at most {AI_MAX_RATE_HZ:g} samples/s over "
                f"all channels, got {rate_hz!r} Hz x {len(chans)} channels"
            )
        self._channels = chans
        owner = [next((m for m in self._models if c in m.channels), self._models[0]) for c in chans]
        self._plan = [
            (
                m,
                tuple(c for c, o in zip(chans, owner, strict=True) if o is m),
                [i for i, o in enumerate(owner) if o is m],
            )
            for m in self._models
            if m in owner
        ]
        transfer_rows = max(1, round(self.transfer_s * rate_hz))
        self._scan = ScanState(chans, float(rate_hz), self._clock.now_s(), transfer_rows)

    def _read(self, *, last: bool) -> ScanBlock:
        """The rows due and not read yet: whole transfers only, unless this is the `last` read."""
        scan = self._scan
        if scan is None:
            return ScanBlock.empty(len(self._channels))
        n_rows = scan.rows_due(self._clock.now_s())
        if not last:
            n_rows -= n_rows % scan.transfer_rows
        if n_rows <= 0:
            return scan.empty
        until_s = scan.row_time_s(scan.rows_read + n_rows - 1)
        parts = [
            m.acquire(scan.t0_s, scan.rate_hz, scan.rows_read, n_rows, chans, until_s)
            for m, chans, _ in self._plan
        ]
        if len(parts) == 1:  # one joint's model reads every column, in scan order
            t_s, codes, volts = parts[0]
        else:
            rows = {p[1].shape[0] for p in parts}
            if len(rows) != 1:
                raise InvalidInput(
                    "simulated joints on different integration grids (give them one plant_step_s)"
                )
            t_s = parts[0][0]
            codes = np.zeros((rows.pop(), len(scan.channels)), dtype=np.int32)
            volts = np.zeros(codes.shape, dtype=np.float64)
            for (_, _, cols), (_, c, v) in zip(self._plan, parts, strict=True):
                codes[:, cols] = c
                volts[:, cols] = v
        scan.rows_read += codes.shape[0]
        return ScanBlock(t_s=t_s, codes=codes, volts=volts)

    def read_available(self) -> ScanBlock:
        return self._read(last=False)

    def stop_scan(self) -> ScanBlock:
        block = self._read(last=True)
        self._scan = None
        return block

    def close(self) -> None:
        self._scan = None
