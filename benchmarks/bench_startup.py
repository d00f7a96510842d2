"""Start-up of a knee_phase1 dry run: from launching `python -m protocol_runner.cli` to the session loop, or
to the first trial.

    python benchmarks/bench_startup.py [--repeats 3] [--checkout DIR] [--until loop|trial]

Each repeat runs the CLI in a fresh process (from `--checkout`, default this one, its src/ first on the
path) with a stop that prints the wall clock and the process's CPU time and exits: `--until loop` (default)
replaces `Runner._run` (everything before the first step: imports, reading and checking the protocol, the
plan, the session folder, the simulated bench), `--until trial` the trial step (also the first set's
calibration check and checklists before it). Prints the median wall and CPU seconds and the load average
(other processes on the machine lengthen the wall time, not the CPU time).
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

def stop(*args):
    print(json.dumps({"t": time.time(), "cpu": time.process_time()}), file=sys.__stdout__, flush=True)
    os._exit(0)

if sys.argv[1] == "trial":
    import protocol_runner.steps.trial as trial
    trial.run = stop  # before the step registry takes it
else:
    import protocol_runner.session.runner as runner
    runner.Runner._run = stop
from protocol_runner.cli import main
main(sys.argv[2:])
"""


def one_start(checkout: Path, session: Path, until: str) -> tuple[float, float]:
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
    cmd = [sys.executable, "-c", CHILD, until, "knee_phase1.yaml", "--dry-run", "--seed", "7"]
    t0 = time.time()
    out = subprocess.run(
        [*cmd, "--session", str(session)], cwd=checkout, env=env, check=True, capture_output=True, text=True
    ).stdout
    mark = json.loads(out.strip().splitlines()[-1])
    return mark["t"] - t0, mark["cpu"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--checkout", type=Path, default=HERE.parent)
    ap.add_argument("--until", choices=("loop", "trial"), default="loop")
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        runs = [one_start(args.checkout, Path(tmp) / f"s{k}", args.until) for k in range(args.repeats)]
    walls, cpus = zip(*runs, strict=True)
    print(
        f"{args.checkout}: start-up to the {args.until} median wall {statistics.median(walls):.2f} s, CPU "
        f"{statistics.median(cpus):.2f} s ({args.repeats} runs: "
        + ", ".join(f"{w:.2f}/{c:.2f}" for w, c in runs)
        + f"); load average {load0:.2f} -> {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
