"""Full campaign dry run against the robot time it simulates (target: >= 300x faster).

    python benchmarks/bench_dry_run.py [--repeats 3] [--only KEYS] [--profile] [--baseline DIR]

Each repeat runs `run-protocol knee_phase1.yaml --dry-run` in a fresh subprocess (so numba's
compilation cache and imports count as they do for a user) and reports the median wall time, the robot
time simulated (trajectories of every run the rig made, including the brace-off scaling runs and the
calibration checks and the parking moves between them: the simulator's clock at the end), their ratio,
and the archive and report sizes. --profile prints where the time goes. It also prints the CPU time of
each run (user + system, the session's worker processes included: less sensitive to the shared machine's
load than the wall time), the load average before and after, and the machine's own speed before and after
(`machine_probe.py`: fixed interpreter, numpy and zlib workloads; compare sittings and machines by them).

--baseline DIR also times the checkout at DIR (its src/ first on the path, run from DIR) in the same
benchmark, alternating the two run by run so that both see the same machine load, and prints both
medians and the ratio of their speeds, and the ratio within each repeat's pair of runs (its median, range
and how many pairs were faster: steadier than the ratio of the medians when the machine drifts).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py

from checkouts import become_subreaper, byte_compile, orphans_cpu_s
from machine_probe import probe_s


def simulated_time_s(archive: Path) -> float | None:
    """The simulator's clock at the end of the session (every motion: trials, scaling runs, checks, parking)."""
    with h5py.File(archive, "r") as f:
        for line in f["session/events"].asstr()[:]:
            event = json.loads(line)
            if event["kind"] == "finished" and "robot time simulated" in event["detail"]:
                return float(event["detail"].rsplit(";", 1)[1].split()[0])
    return None


def robot_time_s(archive: Path) -> float:
    """Seconds of commanded motion recorded in the archive (every trial, kept scaling runs, checks)."""
    total = 0.0
    with h5py.File(archive, "r") as f:

        def visit(name: str, obj: object) -> None:
            nonlocal total
            if isinstance(obj, h5py.Dataset) and name.endswith("command_time_s"):
                t = obj[:]
                if t.size > 1:
                    total += float(t[-1] - t[0] + (t[1] - t[0]))
            if isinstance(obj, h5py.Group) and name.endswith("brace_off/scaling"):
                # scaling runs that were not kept also moved the robot: count them by their length
                runs = int(obj["iteration"].shape[0])
                t = f[name.rsplit("/", 1)[0]]["command_time_s"][:]
                total += (runs - 1) * float(t[-1] - t[0])

        f.visititems(visit)
    return total


def _run_once(
    checkout: Path | None, session: Path, only: str | None, profile: Path | None
) -> tuple[float, float]:
    """One dry run of `checkout` (None: the installed package, from this directory): (wall s, CPU s)."""
    cmd = [sys.executable]
    if profile is not None:
        cmd += ["-m", "cProfile", "-o", str(profile)]
    cmd += ["-m", "protocol_runner.cli", "knee_phase1.yaml", "--dry-run", "--session", str(session)]
    if only:
        cmd += ["--only", only]
    env = dict(os.environ)
    if checkout is not None:
        env["PYTHONPATH"] = str(checkout / "src")
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, cwd=checkout)
    _, status, usage = os.wait4(proc.pid, 0)  # the run's CPU, its reaped workers included
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise SystemExit(f"the dry run of {checkout or 'this checkout'} failed (exit {code})")
    return wall, usage.ru_utime + usage.ru_stime + orphans_cpu_s()


def _summary(walls: list[float], cpus: list[float], robot: float) -> dict[str, object]:
    median = statistics.median(walls) if walls else float("nan")
    return {
        "wall_s_median": round(median, 2),
        "wall_s_runs": [round(w, 2) for w in walls],
        "cpu_s_median": round(statistics.median(cpus), 2) if cpus else None,
        "cpu_s_runs": [round(c, 2) for c in cpus],
        "speedup": round(robot / median, 1),
        "speedup_on_cpu": round(robot / statistics.median(cpus), 1) if cpus else None,
    }


def _paired(before: list[float], after: list[float]) -> dict[str, object]:
    """before / after of each repeat's pair of runs: their median, lowest and highest (3 decimals)."""
    ratios = [b / a for b, a in zip(before, after, strict=True) if a > 0.0]
    if not ratios:
        return {}
    return {
        "median": round(statistics.median(ratios), 3),
        "min": round(min(ratios), 3),
        "max": round(max(ratios), 3),
        "faster_in": f"{sum(r > 1.0 for r in ratios)} of {len(ratios)} pairs",
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", default=None)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--baseline", type=Path, default=None, help="another checkout to time in the same run")
    args = ap.parse_args()
    become_subreaper()
    here = Path(__file__).resolve().parents[1] if args.baseline is not None else None
    checkouts: list[tuple[str, Path | None]] = [("this", here)]
    if args.baseline is not None:
        checkouts.append(("baseline", args.baseline.resolve()))
    for _, checkout in checkouts:
        if checkout is not None:
            byte_compile(checkout / "src")
    walls: dict[str, list[float]] = {name: [] for name, _ in checkouts}
    cpus: dict[str, list[float]] = {name: [] for name, _ in checkouts}
    load0 = os.getloadavg()
    probe0 = probe_s()
    robot = 0.0
    sizes: tuple[int, int] = (0, 0)
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            for name, checkout in checkouts if i % 2 == 0 else checkouts[::-1]:
                session = Path(tmp) / f"{name}{i}"
                profile = Path(tmp) / "prof" if args.profile and i == 0 and name == "this" else None
                wall, cpu = _run_once(checkout, session, args.only, profile)
                if profile is None:
                    walls[name].append(wall)
                    cpus[name].append(cpu)
                if name == "this":
                    robot = simulated_time_s(session / "archive.h5") or robot_time_s(session / "archive.h5")
                    sizes = (
                        (session / "archive.h5").stat().st_size,
                        (session / "report.html").stat().st_size,
                    )
                print(f"run {i + 1} ({name}): {wall:.1f} s wall, {cpu:.1f} s CPU", flush=True)
                shutil.rmtree(session, ignore_errors=True)
        if args.profile:
            import pstats

            pstats.Stats(str(Path(tmp) / "prof")).sort_stats("cumulative").print_stats(30)
    result: dict[str, object] = _summary(walls["this"], cpus["this"], robot)
    ratio = float(result["speedup"])  # type: ignore[arg-type]
    if args.baseline is not None:
        before = _summary(walls["baseline"], cpus["baseline"], robot)
        result["baseline"] = {"checkout": str(args.baseline), **before}
        result["faster_than_baseline_wall"] = round(
            float(before["wall_s_median"]) / float(result["wall_s_median"]),  # type: ignore[arg-type]
            2,
        )
        result["less_cpu_than_baseline"] = round(
            float(before["cpu_s_median"]) / float(result["cpu_s_median"]),  # type: ignore[arg-type]
            2,
        )
        # each repeat's two runs follow each other: their ratio is less sensitive to the machine's drift
        # over the benchmark than the ratio of the medians (one figure per pair, then their median)
        result["paired_wall_ratios"] = _paired(walls["baseline"], walls["this"])
        result["paired_cpu_ratios"] = _paired(cpus["baseline"], cpus["this"])
    result.update(
        {
            "load_average_before_after": [round(load0[0], 2), round(os.getloadavg()[0], 2)],
            "machine_probe_before_after_s": [probe0, probe_s()],
            "robot_time_s": round(robot, 1),
            "target_speedup": 300,
            "archive_mb": round(sizes[0] / 1e6, 1),
            "report_mb": round(sizes[1] / 1e6, 1),
        }
    )
    print(json.dumps(result, indent=2))
    print("PASS" if ratio >= 300 else "FAIL", f"speed-up {ratio:.0f}x (target 300x)")
    print("PASS" if sizes[0] < 100e6 else "FAIL", f"archive {sizes[0] / 1e6:.1f} MB (target < 100 MB)")


if __name__ == "__main__":
    main()
