"""Two Ctrl-C 50 ms apart at random moments of a short dry run: the process must always end, within a
bounded time, without a traceback.

    python benchmarks/bench_double_sigint.py [--tries 50] [--timeout 60] [--seed 1]

Each try starts `run-protocol elbow_example.yaml --dry-run --only 1` in its own process group (as a shell
runs a job), waits a random time between 0.2 s and the length of an uninterrupted run (measured first),
sends SIGINT to the group (as a terminal's Ctrl-C does, the workers included), then again 50 ms later,
and waits at most `--timeout` seconds for the process to end. A process still running then is counted as
hung and killed. Prints how many tries hung (must be 0), the exit codes (130: stopped; 0: the run had
finished before the signals), the tries whose standard error holds a traceback, and the longest time from
the second SIGINT to the end of the process. POSIX only (process groups).
"""

from __future__ import annotations

import argparse
import collections
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ARGS = ["elbow_example.yaml", "--dry-run", "--seed", "7", "--only", "1"]


def start(session: Path, err: Path) -> subprocess.Popen[bytes]:
    with err.open("wb") as f:
        return subprocess.Popen(
            [sys.executable, "-m", "protocol_runner.cli", *ARGS, "--session", str(session)],
            stdout=subprocess.DEVNULL,
            stderr=f,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
            start_new_session=True,
        )


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--tries", type=int, default=50)
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds a try may take to end")
    parser.add_argument("--seed", type=int, default=1, help="seed of the random moments")
    args = parser.parse_args()
    if os.name == "nt":
        print("POSIX only (process groups and SIGINT to a group)")
        return 2
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="double-sigint-"))
    try:
        t0 = time.monotonic()
        proc = start(work / "reference", work / "reference.err")
        code = proc.wait(timeout=600)
        span_s = time.monotonic() - t0
        print(
            f"uninterrupted run: exit {code}, {span_s:.1f} s; {args.tries} tries, timeout {args.timeout:.0f} s"
        )
        codes: collections.Counter[int | str] = collections.Counter()
        tracebacks: list[int] = []
        longest_s = 0.0
        for n in range(args.tries):
            session, err = work / f"s{n}", work / f"s{n}.err"
            delay_s = rng.uniform(0.2, span_s)
            proc = start(session, err)
            time.sleep(delay_s)
            signalled = False
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGINT)
                time.sleep(0.05)
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGINT)
                signalled = True
            t_second = time.monotonic()
            outcome: int | str
            try:
                outcome = proc.wait(timeout=args.timeout)
                if signalled:
                    longest_s = max(longest_s, time.monotonic() - t_second)
            except subprocess.TimeoutExpired:
                outcome = "hung"
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            codes[outcome] += 1
            said = err.read_text(errors="replace")
            if "Traceback" in said:
                tracebacks.append(n)
            if "Traceback" in said or outcome not in (0, 130):
                print("    " + "\n    ".join(said.strip().splitlines()[-40:]))
            print(f"try {n + 1:2d}: signals at {delay_s:5.2f} s: {outcome}", flush=True)
            shutil.rmtree(session, ignore_errors=True)
        print(f"hung: {codes['hung']} of {args.tries}")
        print(
            "exit codes: " + ", ".join(f"{k}: {v}" for k, v in sorted(codes.items(), key=str) if k != "hung")
        )
        print(f"tracebacks on stderr: {len(tracebacks)} {tracebacks if tracebacks else ''}")
        print(f"longest time from the second SIGINT to the end: {longest_s:.1f} s")
        return 1 if codes["hung"] or tracebacks else 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
