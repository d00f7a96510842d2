"""Where a full dry run's time goes: acquisition, unit writing, processing, fits, consolidation, report.

    python benchmarks/bench_time_split.py [--only KEYS] [--checkout DIR]

Runs `run-protocol knee_phase1.yaml --dry-run --yes` once in a subprocess (from `--checkout`, default this
one, with its src/ first on the path) with `benchmarks/time_split/sitecustomize.py` timing a few functions
in every process (session, analysis workers, figure workers), and prints the wall time and, per category,
the seconds spent in the session's main thread, its unit-writer thread and the worker processes. Unlike
cProfile it adds almost nothing per call, so the per-tick loop is not penalised. Prints the load average.
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from checkouts import byte_compile

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", default=None)
    ap.add_argument("--checkout", type=Path, default=HERE.parent)
    args = ap.parse_args()
    byte_compile(args.checkout / "src")
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "split.log"
        env = dict(os.environ)
        env["PR_SPLIT_LOG"] = str(log)
        env["PYTHONPATH"] = os.pathsep.join([str(args.checkout / "src"), str(HERE / "time_split")])
        cmd = [sys.executable, "-m", "protocol_runner.cli", "knee_phase1.yaml", "--dry-run", "--yes"]
        cmd += ["--session", str(Path(tmp) / "s")] + (["--only", args.only] if args.only else [])
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        subprocess.run(
            cmd, check=True, cwd=args.checkout, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        wall = time.perf_counter() - t0
        lines = [line.split() for line in log.read_text().splitlines()]
    main_pid = next(pid for pid, _, cat, _, _ in lines if cat == "session")
    totals: dict[tuple[str, str], float] = collections.defaultdict(float)
    cpu: dict[tuple[str, str], float] = collections.defaultdict(float)
    for pid, thread, cat, value, cpu_s in lines:
        if cat == "process_start":
            continue
        where = (
            "main thread"
            if pid == main_pid and thread == "MainThread"
            else ("writer thread" if pid == main_pid else "workers")
        )
        totals[(cat.replace("_", " "), where)] += float(value)
        cpu[(cat.replace("_", " "), where)] += float(cpu_s)
    print(
        f"{args.checkout}: wall {wall:.1f} s; load average before {load0[0]:.2f}, after {os.getloadavg()[0]:.2f}"
    )
    session = totals.pop(("session", "main thread"), 0.0)
    print(f"  {'category':34s} {'where':14s}   wall    CPU (of the calling thread)")
    print(
        f"  start-up (before the session loop): {wall - session:.1f} s; session loop and report {session:.1f} s"
    )
    for (cat, where), value in sorted(totals.items(), key=lambda kv: -kv[1]):
        print(f"  {cat:34s} {where:14s} {value:6.2f} {cpu[(cat, where)]:6.2f} s")


if __name__ == "__main__":
    main()
