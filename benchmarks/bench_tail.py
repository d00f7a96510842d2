"""The finish of a full dry run: wall time from the last unit written to the process's exit.

    python benchmarks/bench_tail.py [--runs 3] [--checkout DIR] [--only KEYS]

Runs `run-protocol knee_phase1.yaml --dry-run --seed 7` (from `--checkout`, default this one, with its
src/ first on the path) `--runs` times, one after the other. Per run it prints the whole wall time and the
tail: the process's exit (seen by this script) minus the newest modification time of the session's unit
files (the last analysis's unit, normally the last configuration's fit). The tail is the serial finish
(consolidation into archive.h5, the report) that the two cores cannot share; prints the medians.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def one_run(checkout: Path, only: str | None) -> tuple[float, float]:
    """(whole wall s, tail s) of one seeded dry run."""
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "s"
        env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
        cmd = [sys.executable, "-m", "protocol_runner.cli", "knee_phase1.yaml", "--dry-run"]
        cmd += ["--seed", "7", "--session", str(session)] + (["--only", only] if only else [])
        t0 = time.time()
        subprocess.run(
            cmd, check=True, cwd=checkout, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        end = time.time()
        last_unit = max(p.stat().st_mtime for p in (session / "units").glob("*.h5"))
    return end - t0, end - last_unit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--checkout", type=Path, default=HERE.parent)
    ap.add_argument("--only", default=None)
    args = ap.parse_args()
    walls, tails = [], []
    for i in range(args.runs):
        wall, tail = one_run(args.checkout, args.only)
        walls.append(wall)
        tails.append(tail)
        print(f"run {i + 1}: wall {wall:.2f} s, tail (last unit written -> exit) {tail:.3f} s", flush=True)
    print(
        f"{args.checkout}: median wall {statistics.median(walls):.2f} s, "
        f"median tail {statistics.median(tails):.3f} s; load average {os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
