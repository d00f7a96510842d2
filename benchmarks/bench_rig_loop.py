"""Per-tick overhead of `Rig.run_trajectory`'s paced loop, against minimal fake boards.

The fakes do (almost) nothing, so the time per tick is the rig's own Python work: sleep_until, now_s,
write_volts and the list stores, plus a scan read every 10 ticks and the whole-array conversions before and
after. A dry run of the knee campaign executes about a million ticks, so 1 µs per tick is 1 s in total.

Baseline in the same run: a bare Python loop making the same three calls per tick with nothing else.

Run: python benchmarks/bench_rig_loop.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Mapping, Sequence

import numpy as np

from protocol_runner.hardware.conversions import RSST_JOINTS
from protocol_runner.hardware.interfaces import ScanBlock
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyLimits

N_TICKS = 6500  # one 65 s trial at 100 Hz
REPEATS = 7


class NullClock:
    def __init__(self) -> None:
        self.t = 0.0

    def now_s(self) -> float:
        return self.t

    def sleep_until(self, t_s: float) -> None:
        if t_s > self.t:
            self.t = t_s


class NullAO:
    def configure_channel(self, channel: int) -> None:
        pass

    def write_volts(self, channel: int, volts: float) -> int:
        return 32768

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        return dict.fromkeys(volts_by_channel, 32768)

    def close(self) -> None:
        pass


class NullAI:
    def __init__(self) -> None:
        self._empty = ScanBlock.empty(2)

    @property
    def resolution_bits(self) -> int:
        return 12

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        self._empty = ScanBlock.empty(len(channels))

    def read_available(self) -> ScanBlock:
        return self._empty

    def stop_scan(self) -> ScanBlock:
        return self._empty

    def close(self) -> None:
        pass


def main() -> None:
    knee = RSST_JOINTS[9]
    joint = JointConfig(
        name="knee",
        range_deg=knee.range_deg,
        torque_range_nm=knee.torque_range_nm,
        output_channel=0,
        angle_input_channel=0,
        torque_input_channel=1,
        limits=SafetyLimits((0.0, 130.0), 200.0, 2000.0, 20.0, 10.0),
    )
    t = np.arange(N_TICKS) / 100.0
    command = 65.0 + 65.0 * np.sin(2 * np.pi * t / 8.17)

    rig_times = []
    for _ in range(REPEATS):
        rig = Rig([joint], NullAO(), NullAI(), NullClock())
        start = time.perf_counter()
        rig.run_trajectory([command], where="bench")
        rig_times.append(time.perf_counter() - start)

    base_times = []
    for _ in range(REPEATS):
        clock, ao = NullClock(), NullAO()
        volts = command.tolist()
        schedule = (np.arange(N_TICKS) / 100.0).tolist()
        codes = [0] * N_TICKS
        start = time.perf_counter()
        for k in range(N_TICKS):
            clock.sleep_until(schedule[k])
            clock.now_s()
            codes[k] = ao.write_volts(0, volts[k])
        base_times.append(time.perf_counter() - start)

    rig_us = statistics.median(rig_times) / N_TICKS * 1e6
    base_us = statistics.median(base_times) / N_TICKS * 1e6
    print(f"rig loop, {N_TICKS} ticks, median of {REPEATS}: {rig_us:.2f} µs per tick (all included)")
    print(f"baseline: bare loop with the same 3 calls per tick: {base_us:.2f} µs per tick")
    print(f"rig overhead beyond the bare calls: {rig_us - base_us:.2f} µs per tick")
    print(f"one million ticks: {rig_us:.2f} s of loop time with free boards")


if __name__ == "__main__":
    main()
