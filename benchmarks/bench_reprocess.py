"""`run-protocol --report SESSION --reprocess` of a seeded dry run: wall time and CPU time (user + sys of the
command and every process it starts, the report's workers included), median of several runs, against a
target, optionally beside another checkout timed run for run in the same sitting. `--no-reprocess` times
`run-protocol --report SESSION` instead (the report regenerated from the archive as it is; target 10 s).

    python benchmarks/bench_reprocess.py [--session DIR] [--protocol knee_phase1.yaml] [--repeats 3]
                                         [--baseline CHECKOUT] [--target-s 30] [--no-reprocess]

The session (default: a seeded dry run of the protocol made first, `--seed 7`) is copied to a temporary
directory for every run, since `--reprocess` writes its new archive into the session. Each run is a fresh
`python -m protocol_runner.cli` process from this checkout (or `--baseline`'s, with its src/ first on the
path); with `--baseline` the two alternate run by run, so that both see the same load. The machine's load
average is printed before and after: on a shared machine compare the CPU column and the ratio to the
baseline, not wall times taken in different sittings. The per-configuration time of the fits alone is
`bench_fits.py`'s.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from checkouts import become_subreaper, byte_compile, orphans_cpu_s

HERE = Path(__file__).resolve().parents[1]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _seeded_session(protocol: str, tmp: Path) -> Path:
    session = tmp / "seeded"
    print(f"making a seeded dry run of {protocol} (--seed 7) ...", flush=True)
    made = subprocess.run(
        [
            sys.executable,
            "-m",
            "protocol_runner.cli",
            protocol,
            "--dry-run",
            "--seed",
            "7",
            "--session",
            str(session),
        ],
        cwd=HERE,
        env=dict(os.environ, PYTHONPATH=str(HERE / "src")),
        capture_output=True,
        text=True,
    )
    if made.returncode != 0:
        sys.exit(f"the dry run failed (exit {made.returncode}):\n{made.stderr[-2000:]}")
    return session


def _reprocess(checkout: Path, session: Path, tmp: Path, reprocess: bool = True) -> tuple[float, float]:
    """Wall and CPU seconds of one `--report --reprocess` (or `--report`) of a fresh copy of `session`."""
    copy = tmp / "run"
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(session, copy)
    for stale in copy.glob("*.reprocessed*.h5"):
        stale.unlink()
    cmd = [sys.executable, "-m", "protocol_runner.cli", "--report", str(copy)] + (
        ["--reprocess"] if reprocess else []
    )
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
    cpu0, wall0 = _children_cpu_s(), time.perf_counter()
    done = subprocess.run(
        [*cmd, "--output", str(copy / "report.html")], cwd=tmp, env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - wall0
    orphans_cpu_s()  # the analysis workers' fork server, if it outlived the command (`become_subreaper`)
    cpu = _children_cpu_s() - cpu0
    if done.returncode != 0:
        sys.exit(f"--report failed in {checkout} (exit {done.returncode}):\n{done.stderr[-2000:]}")
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--session", type=Path, default=None, help="a dry run's session directory to reprocess")
    ap.add_argument(
        "--protocol", default="knee_phase1.yaml", help="protocol of the seeded dry run made first"
    )
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", type=Path, default=None, help="another checkout to time in the same run")
    ap.add_argument("--target-s", type=float, default=None, help="wall-time target of one run (30 s, 10 s)")
    ap.add_argument("--no-reprocess", action="store_true", help="time `--report` alone")
    args = ap.parse_args()
    become_subreaper()
    reprocess = not args.no_reprocess
    target_s = args.target_s or (30.0 if reprocess else 10.0)
    checkouts = [("this", HERE)] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    for _, checkout in checkouts:
        byte_compile(checkout / "src")
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name, _ in checkouts}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        session = args.session.resolve() if args.session else _seeded_session(args.protocol, tmp)
        for _, checkout in checkouts:  # one untimed run each: numba's cache of this checkout's kernels
            _reprocess(checkout, session, tmp, reprocess)
        for k in range(args.repeats):
            for name, checkout in checkouts if k % 2 == 0 else checkouts[::-1]:
                wall, cpu = _reprocess(checkout, session, tmp, reprocess)
                runs[name].append((wall, cpu))
                print(f"run {k + 1} ({name}): {wall:.1f} s wall, {cpu:.1f} s CPU", flush=True)
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    result: dict[str, object] = {
        name: {
            "wall_s_median": round(statistics.median(w for w, _ in r), 2),
            "cpu_s_median": round(statistics.median(c for _, c in r), 2),
        }
        for name, r in runs.items()
    }
    if args.baseline is not None:
        result["cpu_ratio_baseline_over_this"] = round(
            statistics.median(c for _, c in runs["baseline"]) / statistics.median(c for _, c in runs["this"]),
            3,
        )
    wall = statistics.median(w for w, _ in runs["this"])
    result["target"] = f"{wall:.1f} s wall against {target_s:g} s: {'met' if wall < target_s else 'NOT met'}"
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
