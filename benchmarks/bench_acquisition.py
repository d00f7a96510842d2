"""Acquisition alone: one knee trial through `run_motion` on the simulated rig (the rig's paced loop driving
the simulated boards in simulated time), with a fixed seed, device and trajectory.

    python benchmarks/bench_acquisition.py [--repeats 7] [--periods 8]

The trial is an Appendix A sinusoid (20-110 deg at 50 deg/s, `--periods` periods, 8 like the protocol) with
the knee brace fitted (R1 stops, friction level 2, K2, centre preload), approach and exit included. Prints
the median CPU and wall time, robot time / CPU time, and a checksum of the recorded codes (equal between two
checkouts that record the same data). To compare two checkouts, run it with each one's `src` first on
PYTHONPATH, alternating. The machine's load average is printed: the box is shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import zlib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' knee values (tests/knee_*.py)

from tests.knee_device import KNEE_PARAMS, knee_brace
from tests.knee_rig import knee_joint_config

from protocol_runner.hardware.joint import TrialRecording
from protocol_runner.hardware.motion import run_motion
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.protocol.trajectories import sinusoid_period_s
from protocol_runner.protocol.trajectory_record import Trajectory


def trial(cmd: np.ndarray) -> tuple[float, float, float, TrialRecording]:
    joint = knee_joint_config(max_rate_deg_s=120.0, max_accel_deg_s2=2000.0)
    sim = SimulatedRig([joint], seed=2007, params=KNEE_PARAMS)
    sim.set_device(knee_brace((40.0, 90.0), 3.75, 13.0, 3))
    rig = sim.make_rig()
    sim.begin_step("bench")
    c0, w0 = time.process_time(), time.perf_counter()
    rec = run_motion(rig, [cmd], where="bench")[0]
    return time.process_time() - c0, time.perf_counter() - w0, sim.clock.now_s(), rec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--periods", type=float, default=8.0)
    args = ap.parse_args()
    period = sinusoid_period_s(45.0, 50.0)
    traj = Trajectory("sinusoid", args.periods * period, mean_deg=65.0, amplitude_deg=45.0, period_s=period)
    cmd = sample_trajectory(traj, 100.0, Path("."))
    trial(cmd[:200])  # numba's cache and first-call costs out of the way
    results = [trial(cmd) for _ in range(args.repeats)]
    robot_s, rec = results[0][2], results[0][3]
    codes = [getattr(rec, name) for name in ("command_codes", "angle_codes", "torque_codes", "stream_deg")]
    checksum = zlib.crc32(b"".join(np.ascontiguousarray(a).tobytes() for a in codes))
    print(
        f"one knee trial: {cmd.size} trajectory ticks, {robot_s:.1f} s of robot time with approach and exit"
    )
    print(f"load average {' / '.join(f'{x:.2f}' for x in os.getloadavg())} (1 / 5 / 15 min)")
    cpu = statistics.median(r[0] for r in results)
    wall = statistics.median(r[1] for r in results)
    print(f"  CPU {cpu * 1e3:7.1f} ms  wall {wall * 1e3:7.1f} ms  {robot_s / cpu:6.0f}x robot time (CPU)")
    print(f"  recorded codes: crc32 {checksum:08x}")


if __name__ == "__main__":
    main()
