"""Idle core time during a full dry run: how much of the machine's CPU the run leaves unused, and when.

    python benchmarks/bench_idle.py [--runs 3] [--checkout DIR] [--window 0.5]

A dry run is CPU-bound on the 2-core machine: its wall time is about (its CPU + the cores' idle time) / 2,
so the idle core-seconds are what better overlap could still win, and the CPU the rest. Each run starts
`run-protocol knee_phase1.yaml --dry-run` (from `--checkout`, default this one, its src/ first on the
path) and samples the machine's idle time (/proc/stat, idle + iowait, every 20 ms) until it exits. Prints,
per run, the wall time, the idle core-seconds in all and in the first and last second, and the idle
core-seconds per `--window` seconds; then the medians. Linux only. The machine's idle time counts every
process: run it on an otherwise quiet machine (the load average is printed before and after).
"""

from __future__ import annotations

import argparse
import bisect
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]


def idle_core_s() -> float:
    """The machine's idle + iowait time so far, in core-seconds."""
    with open("/proc/stat") as f:
        fields = f.readline().split()
    return (int(fields[4]) + int(fields[5])) / os.sysconf("SC_CLK_TCK")


def one_run(checkout: Path, window_s: float) -> tuple[float, float, float, float, list[float]]:
    """Wall time, idle core-seconds in all, in the first and the last second, and per window."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
        cmd = [sys.executable, "-m", "protocol_runner.cli", "knee_phase1.yaml", "--dry-run"]
        t0 = time.perf_counter()
        i0 = idle_core_s()
        log = open(Path(tmp) / "stderr.txt", "w+")  # noqa: SIM115 (read back below on failure)
        proc = subprocess.Popen(
            [*cmd, "--session", str(Path(tmp) / "s")],
            cwd=checkout,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=log,
        )
        samples = [(0.0, 0.0)]
        while proc.poll() is None:
            time.sleep(0.02)
            samples.append((time.perf_counter() - t0, idle_core_s() - i0))
        wall = time.perf_counter() - t0
        samples.append((wall, idle_core_s() - i0))
        log.seek(0)
        err = log.read()
        log.close()
        if proc.returncode != 0:
            sys.exit(f"the dry run failed (exit {proc.returncode}):\n{err[-2000:]}")
    times = [t for t, _ in samples]

    def at(t: float) -> float:
        return samples[min(bisect.bisect_left(times, t), len(samples) - 1)][1]

    windows = [at(t + window_s) - at(t) for t in [k * window_s for k in range(int(wall / window_s) + 1)]]
    return wall, samples[-1][1], at(1.0), samples[-1][1] - at(wall - 1.0), windows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--checkout", type=Path, default=HERE)
    ap.add_argument("--window", type=float, default=0.5, help="seconds per entry of the idle timeline")
    args = ap.parse_args()
    if not Path("/proc/stat").exists():
        sys.exit("bench_idle.py reads /proc/stat: Linux only")
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    rows = []
    for k in range(args.runs):
        wall, idle, first, last, windows = one_run(args.checkout.resolve(), args.window)
        rows.append((wall, idle, first, last))
        timeline = " ".join(f"{j * args.window:.1f}:{v:.2f}" for j, v in enumerate(windows))
        print(
            f"run {k + 1}: wall {wall:.2f} s, idle {idle:.2f} core-s (first second {first:.2f}, last {last:.2f})"
        )
        print(f"  idle core-s per {args.window:g} s: {timeline}")
    wall, idle, first, last = (statistics.median(c) for c in zip(*rows, strict=True))
    print(
        f"median: wall {wall:.2f} s, idle {idle:.2f} core-s (first second {first:.2f}, last {last:.2f}); "
        f"load average after: {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
