"""Multi-joint output loop: tick jitter with three joints against one, in the same run, and the
leg campaign's dry-run wall time against the robot time it simulates.

Jitter: the paced loop runs on the simulator's real-time clock (`realtime=True`: it sleeps until each
tick, as on the rig) for DURATION_S of a gait-like motion, once with hip, knee and ankle (one synchronous
update of three channels per tick) and once with the knee alone (one write per tick), both through `Rig`,
alternating REPEATS times; it prints the tick lateness (write time minus schedule) p50/p99/max of each.
Dry runs: each protocol given (default leg_phase2 and suit_phase4, the whole suit's twelve joints) dry-run
in-process REPEATS times: the median wall time, the session process's CPU time (not its analysis workers') and the
simulated robot time.

Run: python benchmarks/bench_multi_joint.py [--protocol leg_phase2 ...] [--repeats N] [--no-jitter]
(the jitter runs take real time, about 20 s; a suit dry run a few minutes)
"""

from __future__ import annotations

import argparse
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from protocol_runner.commands import run
from protocol_runner.hardware.motion import run_motion
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.session.rigs import joint_config

REPO = Path(__file__).resolve().parents[1]
LEG = REPO / "protocols" / "leg_phase2.yaml"
DURATION_S = 8.0
REPEATS = 2


def _motion(n: int) -> list[np.ndarray]:
    t = np.arange(n) / 100.0
    return [
        20 + 10 * np.sin(2 * np.pi * t / 4),
        45 + 20 * np.sin(2 * np.pi * t / 4),
        8 * np.sin(2 * np.pi * t / 4),
    ]


def _stats(x: np.ndarray) -> str:
    ms = 1e3 * x
    return f"p50 {np.percentile(ms, 50):.3f} ms, p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms"


def _cpu_s() -> float:
    """CPU time of this process: the session's own (the rig loop, the simulator, the archive); the analysis
    workers' is not counted (they are the fork server's children, not this process's)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def dry_run(protocol: Path) -> tuple[int, float, float, str]:
    """One seeded dry run of `protocol`: exit code, wall s, session CPU s, robot time text."""
    with tempfile.TemporaryDirectory() as tmp:
        start, cpu = time.perf_counter(), _cpu_s()
        code = run(
            str(protocol),
            dry_run=True,
            session=Path(tmp) / "s",
            seed=1,
            yes=True,
            only=None,
            realtime=False,
            quiet=True,
        )
        wall, cpu = time.perf_counter() - start, _cpu_s() - cpu
        journal = (Path(tmp) / "s" / "journal.jsonl").read_text()
        robot = journal.split("s of robot time simulated")[0].rsplit("; ", 1)[-1].strip()
    return code, wall, cpu, robot


def jitter() -> None:
    loaded = load_protocol(LEG)
    joints = [joint_config(loaded, r) for r in loaded.protocol.rigs]
    params = [SimulatorParams(**dict(r.simulator)) for r in loaded.protocol.rigs]
    n = int(DURATION_S * 100)
    three, one = [], []
    for _ in range(REPEATS):
        multi = SimulatedRig(joints, params=params, seed=1, realtime=True)
        three.append(run_motion(multi.make_rig(), _motion(n), where="bench")[0].tick_lateness_s)
        single = SimulatedRig(joints[1:2], seed=1, params=params[1], realtime=True)
        one.append(run_motion(single.make_rig(), _motion(n)[1:2], where="bench")[0].tick_lateness_s)
    print(
        f"tick lateness, 3 joints (one synchronous update of 3 channels per tick): {_stats(np.concatenate(three))}"
    )
    print(
        f"tick lateness, 1 joint  (one write per tick):                          {_stats(np.concatenate(one))}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--protocol", action="append", help="a shipped protocol's name (repeatable)")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--no-jitter", action="store_true")
    args = parser.parse_args()
    if not args.no_jitter:
        jitter()
    for name in args.protocol or ["leg_phase2", "suit_phase4"]:
        runs = [dry_run(REPO / "protocols" / f"{name}.yaml") for _ in range(args.repeats)]
        codes = {r[0] for r in runs}
        wall = statistics.median(r[1] for r in runs)
        cpu = statistics.median(r[2] for r in runs)
        print(
            f"{name} dry run: exit {sorted(codes)}, median of {len(runs)}: {wall:.1f} s wall, {cpu:.1f} s CPU "
            f"for {runs[0][3]} s of simulated robot time"
        )


if __name__ == "__main__":
    main()
