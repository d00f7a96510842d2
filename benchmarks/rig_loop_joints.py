"""CPU per tick of the rig's paced loop for one joint and for the RSST's twelve joints, in the same run.

`Rig.run_trajectory` sends a 65 s trial at 100 Hz to minimal fake boards (they do almost nothing: the time
measured is the rig's own Python work per tick - the schedule, the write of every joint's volts, the list
stores, a scan read every 10 ticks - plus the whole-array conversions before and after). One joint makes one
`write_volts` per tick; twelve make one `write_volts_sync` of twelve channels per tick, scanning 24
channels. CPU time (`time.process_time`) and wall time, medians of REPEATS runs alternating both cases.

Run: python benchmarks/rig_loop_joints.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Sequence

import numpy as np

from bench_rig_loop import NullAI, NullAO, NullClock  # the do-nothing boards
from protocol_runner.hardware.conversions import RSST_JOINTS
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyLimits

N_TICKS = 6500  # one 65 s trial at 100 Hz
REPEATS = 7


def rsst_joints() -> list[JointConfig]:
    """The RSST's twelve joints on outputs 0-11 and inputs 0-23, each with a motion inside its range."""
    joints = []
    for k, j in enumerate(RSST_JOINTS.values()):
        lo, hi = j.range_deg
        joints.append(
            JointConfig(
                name=j.name,
                range_deg=j.range_deg,
                torque_range_nm=j.torque_range_nm,
                output_channel=k,
                angle_input_channel=2 * k,
                torque_input_channel=2 * k + 1,
                input_rate_hz=500.0,  # 24 channels x 500 Hz within a 12 kS/s scan
                limits=SafetyLimits((lo, hi), 200.0, 2000.0, (lo + hi) / 2, 10.0),
            )
        )
    return joints


def commands(joints: Sequence[JointConfig]) -> list[np.ndarray]:
    t = np.arange(N_TICKS) / 100.0
    out = []
    for j in joints:
        lo, hi = j.limits.range_deg
        out.append((lo + hi) / 2 + 0.4 * (hi - lo) * np.sin(2 * np.pi * t / 8.17))
    return out


def run_once(joints: Sequence[JointConfig], cmds: list[np.ndarray]) -> tuple[float, float]:
    rig = Rig(joints, NullAO(), NullAI(), NullClock())
    cpu, wall = time.process_time(), time.perf_counter()
    rig.run_trajectory(cmds, where="bench")
    return time.process_time() - cpu, time.perf_counter() - wall


def main() -> None:
    twelve = rsst_joints()
    one = twelve[9:10]  # the knee
    cases = {"1 joint": (one, commands(one)), "12 joints": (twelve, commands(twelve))}
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in cases}
    for _ in range(REPEATS):
        for name, (joints, cmds) in cases.items():
            times[name].append(run_once(joints, cmds))
    for name, runs in times.items():
        cpu_us = statistics.median(c for c, _ in runs) / N_TICKS * 1e6
        wall_us = statistics.median(w for _, w in runs) / N_TICKS * 1e6
        print(f"{name:>9}: {cpu_us:6.2f} µs CPU per tick, {wall_us:6.2f} µs wall (median of {REPEATS})")


if __name__ == "__main__":
    main()
