"""Where a full dry run's time goes: acquisition, unit writing, processing, fits, consolidation, report.

    python benchmarks/bench_time_split.py [--only KEYS] [--checkout DIR]

Runs `run-protocol knee_phase1.yaml --dry-run --yes` once in a subprocess (from `--checkout`, default this
one, with its src/ first on the path) with `benchmarks/time_split/sitecustomize.py` timing a few functions
in every process (session, analysis workers, figure workers), and prints the wall time and, per category,
the seconds spent in the session's main thread, its unit-writer thread and the worker processes. Unlike
cProfile it adds almost nothing per call, so the per-tick loop is not penalised. Prints the load average.

It also reads every thread's CPU time (user + system) of the run's processes from /proc every 0.1 s and
prints it by process (the session, its fork server, each worker) and thread (named from the log; a thread
that ends loses at most its last 0.1 s), with what no category covers: imports, the fork server's preload,
the compression threads, task hand-over. Without /proc (not Linux) that table is left out.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

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
        run = subprocess.Popen(
            cmd, cwd=args.checkout, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        threads, parents = _thread_cpu_until_exit(run)
        if run.returncode != 0:
            sys.exit(f"the dry run failed (exit {run.returncode})")
        wall = time.perf_counter() - t0
        lines = [line.split() for line in log.read_text().splitlines()]
    main_pid = next(pid for pid, _, cat, _, _ in lines if cat == "session")
    totals: dict[tuple[str, str], float] = collections.defaultdict(float)
    cpu: dict[tuple[str, str], float] = collections.defaultdict(float)
    for pid, thread, cat, value, cpu_s in lines:
        if cat in ("process_start", "thread_start"):
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
    if threads:
        _print_thread_cpu(threads, parents, lines, main_pid)


def _thread_cpu_until_exit(
    run: subprocess.Popen[Any],
) -> tuple[dict[tuple[int, int], float], dict[int, int]]:
    """CPU seconds (user + system) of every thread of `run` and its descendants, read from /proc every
    0.1 s until `run` exits (the last reading of each thread), and each such process's parent; both empty
    without /proc."""
    if not Path("/proc/self/task").is_dir():
        run.wait()
        return {}, {}
    tick = os.sysconf("SC_CLK_TCK")
    seen: dict[tuple[int, int], float] = {}
    family_parents: dict[int, int] = {}
    while run.poll() is None:
        parents: dict[int, int] = {}
        for entry in os.scandir("/proc"):
            if entry.name.isdigit():
                with_stat = _stat_fields(f"/proc/{entry.name}/stat")
                if with_stat is not None:
                    parents[int(entry.name)] = int(with_stat[1])
        family = {run.pid}
        grown = True
        while grown:
            more = {pid for pid, ppid in parents.items() if ppid in family} - family
            grown = bool(more)
            family |= more
        family_parents.update({pid: parents[pid] for pid in family if pid in parents})
        for pid in family:
            with contextlib.suppress(OSError):
                for task in os.scandir(f"/proc/{pid}/task"):
                    fields = _stat_fields(f"/proc/{pid}/task/{task.name}/stat")
                    if fields is not None:
                        seen[(pid, int(task.name))] = (int(fields[11]) + int(fields[12])) / tick
        time.sleep(0.1)
    return seen, family_parents


def _stat_fields(path: str) -> list[str] | None:
    """The fields of a /proc stat file after the command name (state first), or None once it is gone."""
    try:
        with open(path) as f:
            text = f.read()
    except OSError:
        return None
    return text[text.rindex(")") + 2 :].split()


# categories timed inside another one of the same thread (not counted twice in what the categories cover)
NESTED = {"acquisition"}


def _print_thread_cpu(
    threads: dict[tuple[int, int], float], parents: dict[int, int], lines: list[list[str]], main_pid: str
) -> None:
    """The table of CPU by process and thread; for each thread, the CPU outside every category (for the
    session's main thread: outside its session loop, which holds its categories)."""
    names = {(int(pid), int(tid)): name for pid, name, cat, tid, _ in lines if cat == "thread_start"}
    workers = sorted(
        {int(pid) for pid, _, cat, _, _ in lines if pid != main_pid and cat in ("fits", "processing")}
    )
    covered: dict[tuple[int, str], float] = collections.defaultdict(float)
    loop: dict[tuple[int, str], float] = {}
    for pid, thread, cat, _, cpu_s in lines:
        if cat == "session":
            loop[(int(pid), thread)] = loop.get((int(pid), thread), 0.0) + float(cpu_s)
        elif cat not in ("process_start", "thread_start") and cat not in NESTED:
            covered[(int(pid), thread)] += float(cpu_s)
    covered.update(loop)
    per_process: dict[int, float] = collections.defaultdict(float)
    for (pid, _), seconds in threads.items():
        per_process[pid] += seconds
    servers = {parents[w] for w in workers if w in parents}

    def role(pid: int) -> str:
        if pid == int(main_pid):
            return "session"
        if pid in workers:
            return f"worker {workers.index(pid) + 1}"
        return "fork server" if pid in servers else f"process {pid}"

    print(f"  CPU by process and thread (/proc, every 0.1 s): {sum(per_process.values()):.1f} s in all")
    print(f"  {'process / thread':32s}    CPU  in no category")
    for pid, total in sorted(per_process.items(), key=lambda kv: -kv[1]):
        if total < 0.05:
            continue
        print(f"  {role(pid):32s} {total:6.2f} s")
        for (p, tid), seconds in sorted(threads.items(), key=lambda kv: -kv[1]):
            if p == pid and seconds >= 0.05:
                name = "MainThread" if tid == pid else names.get((pid, tid), f"thread {tid}")
                outside = max(0.0, seconds - covered.get((pid, name), 0.0))
                print(f"    {name:30s} {seconds:6.2f} s {outside:6.2f} s")


if __name__ == "__main__":
    main()
