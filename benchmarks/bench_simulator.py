"""Throughput of the DAQ simulator (target: >= 1,000,000 input samples per second on one core) and the
cost of one whole simulated 65 s trial through `Rig.run_trajectory`.

Measured, each as the median of several repeats (the numba kernel is compiled/loaded before timing):

1. plant kernel only: `JointPlant.advance` over a 65 s sinusoid, samples/s;
2. simulated boards as the Rig drives them: a USB-3105 write every 10 ms and a DT9814 scan read every
   100 ms, samples/s — and the same with 1 s reads (in simulated time the board hands its rows over in
   1 s transfers, so both make one compiled call per second of scan);
3. a whole trial: the knee's Appendix A sinusoid 65 + 65 sin(2πt/8.17) for 65 s, brace K2 / R3 / level 2,
   through `Rig.run_trajectory` (safety check, LUTs, paced loop, conversions), in ms, compared against
   the 65 s of robot time it simulates (a dry run must be >= 300x faster than the robot).

Run: python benchmarks/bench_simulator.py [--repeats N]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.knee_device import KNEE_PARAMS, knee_brace  # noqa: E402
from tests.knee_rig import knee_joint_config  # noqa: E402

from protocol_runner.hardware.joint import JointConfig  # noqa: E402
from protocol_runner.hardware.simulator.daq import SimulatedRig  # noqa: E402
from protocol_runner.hardware.simulator.plant import JointPlant  # noqa: E402

TRIAL_S = 65.0
OUTPUT_RATE_HZ = 100.0
INPUT_RATE_HZ = 1000.0
PERIOD_S = 8.17  # thesis Table 6, Rr3 at full speed


def knee() -> JointConfig:
    return knee_joint_config(max_rate_deg_s=100.0, max_accel_deg_s2=1000.0)


BRACE = knee_brace((0.0, 130.0), 3.75, 13.0, 3)
COMMAND_DEG = 65.0 + 65.0 * np.sin(
    2.0 * np.pi * np.arange(int(TRIAL_S * OUTPUT_RATE_HZ)) / OUTPUT_RATE_HZ / PERIOD_S
)


def median_s(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """Median wall time and median CPU time of this process (the machine may be shared: CPU time is
    the one-core figure, wall time what a user waits)."""
    fn()  # warm-up (numba cache load, first-call costs)
    wall, cpu = [], []
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def line(label: str, n: int, wall: float, cpu: float) -> str:
    return (
        f"{label:34s} {n / cpu / 1e6:5.2f} M samples/s CPU ({cpu * 1e3:6.1f} ms)   "
        f"{n / wall / 1e6:5.2f} M samples/s wall ({wall * 1e3:6.1f} ms)"
    )


def bench_kernel() -> int:
    plant = JointPlant(KNEE_PARAMS, (0.0, 130.0), (-84.8, 84.8))
    plant.set_device(BRACE)
    plant.reset(20.0)
    dt = KNEE_PARAMS.plant_step_s
    per_tick = round(1.0 / OUTPUT_RATE_HZ / dt)
    plant.push_commands(np.arange(COMMAND_DEG.size, dtype=np.int64) * per_tick, COMMAND_DEG)
    n = int(TRIAL_S * INPUT_RATE_HZ)
    steps = np.round(np.arange(n) / INPUT_RATE_HZ / dt).astype(np.int64)
    angle, _ = plant.advance(int(steps[-1]), steps)
    return int(angle.shape[0])


_BOARDS = SimulatedRig([knee()], seed=1, params=KNEE_PARAMS)
_BOARDS.set_device(BRACE)
_VOLTS = (-10.0 + 20.0 * COMMAND_DEG / 130.0).tolist()


def bench_boards(read_every_ticks: int) -> int:
    """The boards driven as the Rig drives them, without the Rig: write, sleep, read every N ticks."""
    sim = _BOARDS
    sim.begin_step("bench")
    clock, ao, ai = sim.clock, sim.ao, sim.ai
    t0 = clock.now_s()
    ai.start_scan([8, 20], INPUT_RATE_HZ)
    n = 0
    for k, v in enumerate(_VOLTS):
        clock.sleep_until(t0 + k / OUTPUT_RATE_HZ)
        ao.write_volts(8, v)
        if (k + 1) % read_every_ticks == 0:
            n += ai.read_available().n_samples
    clock.sleep_until(t0 + len(_VOLTS) / OUTPUT_RATE_HZ)
    n += ai.stop_scan().n_samples
    return n


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    repeats = args.repeats

    print(f"median of {repeats} runs; one 65 s trial = {int(TRIAL_S * INPUT_RATE_HZ)} input rows")
    n = bench_kernel()
    print(line("plant kernel only", n, *median_s(bench_kernel, repeats)))
    for every, label in ((10, "boards, reads every 100 ms (Rig)"), (100, "boards, reads every 1 s")):
        n = bench_boards(every)
        print(line(label, n, *median_s(lambda every=every: bench_boards(every), repeats)))  # type: ignore[misc]

    sim = SimulatedRig([knee()], seed=1, params=KNEE_PARAMS)
    sim.set_device(BRACE)
    rig = sim.make_rig()

    def whole_trial() -> int:
        sim.begin_step("bench-trial")
        return rig.run_trajectory([COMMAND_DEG], where="bench-trial")[0].n_samples

    n = whole_trial()
    wall, cpu = median_s(whole_trial, repeats)
    print(line("whole 65 s trial via Rig", n, wall, cpu))
    print(
        f"whole trial: {wall * 1e3:.1f} ms wall, {cpu * 1e3:.1f} ms CPU for {TRIAL_S:.0f} s of robot time: "
        f"{TRIAL_S / wall:,.0f}x (wall) / {TRIAL_S / cpu:,.0f}x (CPU) faster than the robot (target >= 300x)"
    )


if __name__ == "__main__":
    main()
