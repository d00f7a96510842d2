"""Start-up of a knee_phase1 dry run: from launching `python -m protocol_runner.cli` to the session loop.

    python benchmarks/bench_startup.py [--repeats 3] [--checkout DIR]

Each repeat runs the CLI in a fresh process (from `--checkout`, default this one, its src/ first on the
path) whose `Runner._run` is replaced by a stop that prints the wall clock and the process's CPU time and
exits: everything before the first step (imports, reading and checking the protocol, the plan, the session
folder, the simulated bench) is measured, nothing after it. Prints the median wall and CPU seconds and the
load average (other processes on the machine lengthen the wall time, not the CPU time).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

CHILD = """
import json, os, sys, time
import protocol_runner.session.runner as runner

def stop(self):
    print(json.dumps({"t": time.time(), "cpu": time.process_time()}), file=sys.__stdout__, flush=True)
    os._exit(0)

runner.Runner._run = stop
from protocol_runner.cli import main
main(sys.argv[1:])
"""


def one_start(checkout: Path, session: Path) -> tuple[float, float]:
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
    cmd = [sys.executable, "-c", CHILD, "knee_phase1.yaml", "--dry-run", "--yes", "--seed", "7"]
    t0 = time.time()
    out = subprocess.run(
        cmd + ["--session", str(session)], cwd=checkout, env=env, check=True, capture_output=True, text=True
    ).stdout
    mark = json.loads(out.strip().splitlines()[-1])
    return mark["t"] - t0, mark["cpu"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--checkout", type=Path, default=HERE.parent)
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        runs = [one_start(args.checkout, Path(tmp) / f"s{k}") for k in range(args.repeats)]
    walls, cpus = zip(*runs, strict=True)
    print(
        f"{args.checkout}: start-up median wall {statistics.median(walls):.2f} s, CPU "
        f"{statistics.median(cpus):.2f} s ({args.repeats} runs: "
        + ", ".join(f"{w:.2f}/{c:.2f}" for w, c in runs)
        + f"); load average {load0:.2f} -> {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
