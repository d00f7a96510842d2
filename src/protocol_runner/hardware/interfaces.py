"""The small interfaces that real USB drivers and the DAQ simulator both satisfy (structural typing).

Nothing here inherits from anything: a class satisfies `AnalogOutput` by having the methods. Steps receive
a rig (see `hardware/rig.py`) that binds one of each to the protocol's joint and channels.

Units: volts (V) on the wire side, seconds (s) for time. Raw codes are the board's own integers.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt


@runtime_checkable
class Clock(Protocol):
    """Monotonic time. The real clock sleeps; the simulated clock jumps (simulated time, no sleeping)."""

    def now_s(self) -> float:
        """Seconds since an arbitrary, fixed origin."""
        ...

    def sleep_until(self, t_s: float) -> None:
        """Return when `now_s() >= t_s` (at once if that time has passed)."""
        ...


@runtime_checkable
class AnalogOutput(Protocol):
    """A software-paced analog output board (the MCC USB-3105 class): one value per channel at a time."""

    def configure_channel(self, channel: int) -> None:
        """Set the channel to the ±10 V range. On the USB-3105 this also drives the pin to 0 V: call it
        once before a run, never inside the loop."""
        ...

    def write_volts(self, channel: int, volts: float) -> int:
        """Output `volts` on `channel` now; return the raw 16-bit code that was sent."""
        ...

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        """Output several channels with one synchronous update; return the codes sent per channel."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class ScanBlock:
    """Samples that arrived from a running input scan.

    `t_s[i]` is the time of scan row `i` on the rig's clock; `codes[i, j]` is the raw code of the j-th
    scanned channel (in the order given to `start_scan`) and `volts[i, j]` the same value in volts,
    converted by the board's own code -> volts rule.
    """

    t_s: npt.NDArray[np.float64]
    codes: npt.NDArray[np.int32]
    volts: npt.NDArray[np.float64]

    @property
    def n_samples(self) -> int:
        return int(self.t_s.shape[0])

    @staticmethod
    def empty(n_channels: int) -> ScanBlock:
        return ScanBlock(
            t_s=np.zeros(0, dtype=np.float64),
            codes=np.zeros((0, n_channels), dtype=np.int32),
            volts=np.zeros((0, n_channels), dtype=np.float64),
        )

    @staticmethod
    def concatenate(blocks: Sequence[ScanBlock], n_channels: int) -> ScanBlock:
        if not blocks:
            return ScanBlock.empty(n_channels)
        return ScanBlock(
            t_s=np.concatenate([b.t_s for b in blocks]),
            codes=np.concatenate([b.codes for b in blocks], axis=0),
            volts=np.concatenate([b.volts for b in blocks], axis=0),
        )


@runtime_checkable
class AnalogInput(Protocol):
    """A hardware-paced analog input scan (DT9814 / USB-1608FS-Plus class)."""

    @property
    def resolution_bits(self) -> int: ...

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        """Start scanning `channels` at `rate_hz` rows per second; the first row is at the current clock."""
        ...

    def read_available(self) -> ScanBlock:
        """Return every row acquired since the last read (possibly none). Never blocks for long."""
        ...

    def stop_scan(self) -> ScanBlock:
        """Stop the scan and return the rows not read yet."""
        ...

    def close(self) -> None: ...


class LoopTap(Protocol):
    """Watches the paced output loop for the live monitor (`monitor/live.py`): told where a run starts
    (with every joint's commanded angles, ticks x joints) and handed each scan block as the loop reads
    it, with every joint's columns (joint k's angle in column 2k, its torque in 2k + 1). Both calls return
    within microseconds and never raise."""

    def start(self, where: str, command_deg: npt.NDArray[np.float64], t0_s: float) -> None: ...

    def scan(self, block: ScanBlock) -> None: ...
