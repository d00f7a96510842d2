"""The simulator's DT9814 stand-in: a hardware-paced scan whose reads integrate the simulated robot up to
the clock (`daq._RigModel.acquire`), and the block path's read after a block of writes (`send_block`)."""

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


class RobotModel(Protocol):
    """What the scan reads from: the simulated robot (`daq._RigModel`)."""

    def acquire(
        self, t0_s: float, rate_hz: float, first_row: int, n_rows: int, channels: Sequence[int], now_s: float
    ) -> tuple[FloatArray, npt.NDArray[np.int32], FloatArray]: ...

    def send_block(
        self, times_s: FloatArray, volts: FloatArray, channel: int, scan: ScanState | None
    ) -> tuple[npt.NDArray[np.int64], FloatArray, npt.NDArray[np.int32], FloatArray]: ...


class ScanState:
    """A running hardware-paced scan: its channels, rate, start and rows handed out so far."""

    def __init__(self, channels: tuple[int, ...], rate_hz: float, t0_s: float) -> None:
        self.channels = channels
        self.rate_hz = rate_hz
        self.t0_s = t0_s
        self.rows_read = 0

    def rows_due(self, now_s: float) -> int:
        """Rows acquired by `now_s` and not yet read (row i at t0 + i / rate; the first at t0)."""
        n_due = math.floor((now_s - self.t0_s) * self.rate_hz + 1e-9) + 1
        return max(0, n_due - self.rows_read)


class SimulatedAnalogInput:
    """A DT9814 stand-in: a hardware-paced scan of 12-bit ±10 V two's-complement codes. Reading it
    integrates the simulated robot up to the clock (lazily) and returns the rows acquired since."""

    def __init__(self, model: RobotModel, clock: SimulatedClock) -> None:
        self._model = model
        self._clock = clock
        self._channels: tuple[int, ...] = ()
        self._scan: ScanState | None = None

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
        self._scan = ScanState(chans, float(rate_hz), self._clock.now_s())

    def _read(self, now_s: float) -> ScanBlock:
        scan = self._scan
        if scan is None:
            return ScanBlock.empty(len(self._channels))
        n_rows = scan.rows_due(now_s)
        if n_rows <= 0:
            return ScanBlock.empty(len(self._channels))
        t_s, codes, volts = self._model.acquire(
            scan.t0_s, scan.rate_hz, scan.rows_read, n_rows, scan.channels, now_s
        )
        scan.rows_read += codes.shape[0]
        return ScanBlock(t_s=t_s, codes=codes, volts=volts)

    def read_after_writes(
        self, times_s: FloatArray, volts: FloatArray, channel: int
    ) -> tuple[npt.NDArray[np.int64], ScanBlock]:
        """The block path's half on this board: the writes' codes, and the rows due at the last write."""
        scan = self._scan
        codes, t_s, row_codes, row_volts = self._model.send_block(times_s, volts, channel, scan)
        if scan is None:
            return codes, ScanBlock.empty(len(self._channels))
        scan.rows_read += row_codes.shape[0]
        return codes, ScanBlock(t_s=t_s, codes=row_codes, volts=row_volts)

    def read_available(self) -> ScanBlock:
        return self._read(self._clock.now_s())

    def stop_scan(self) -> ScanBlock:
        block = self._read(self._clock.now_s())
        self._scan = None
        return block

    def close(self) -> None:
        self._scan = None
