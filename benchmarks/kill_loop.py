"""SIGKILL at a random moment of a short seeded dry run, then `--resume` to the end, many times: the resumed
session must always equal an uninterrupted run's, with no finished step redone and none lost.

    python benchmarks/kill_loop.py [--kills 50] [--timeout 300] [--seed 1] [--only 1]

An uninterrupted seeded run (`run-protocol elbow_example.yaml --dry-run --seed 7 --only 1`) is made first:
the reference, and the length of a run. Then, until `--kills` kills were made (or twice as many tries),
each try starts the same run in a fresh session directory and its own process group, waits a random time
between 0.2 s and that length, and sends SIGKILL to the session process (`kill -9 PID`: nothing of it
runs on; its analysis workers and multiprocessing's fork server, left without it, must end by
themselves). A run that had already ended is not a kill; one killed before its session began (no
`session.json` yet) has nothing to resume. A killed session is resumed (`run-protocol --resume DIR`),
and checked:

- the resume ends with exit 0 within `--timeout` seconds (else counted as a hang and killed);
- `run-protocol --verify DIR` passes (every dataset against its checksum, every journaled unit present);
- no step finished at the kill (journaled complete: `inspect_journal`, read without repairing) was
  journaled again by the resume (redone), and each keeps its unit's checksum;
- every step of the reference is journaled complete (none lost);
- `tools/compare_archives.py` finds the same values as in the reference archive (what a resume adds by
  design aside: its events, the calibration re-check of a resume inside a set, and the attribute
  checksums, which cover wall-clock times).

Prints each try, then the counts (runs, kills, clean resumes, redone steps and trials, lost steps,
mismatches, hangs, kills after which a process of the run still ran 5 s later, what it was is printed)
and the median and longest resume time. Exit 1 if any resume was not clean. POSIX only (process groups). Run it niced on a shared machine:
`nice -n 10 python benchmarks/kill_loop.py`.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import os
import random
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from protocol_runner.session.journal import inspect_journal

PROTOCOL = "elbow_example.yaml"
COMPARE = Path(__file__).resolve().parents[1] / "tools" / "compare_archives.py"
ORPHAN_GRACE_S = 5.0


def cli(*args: str, log: Path) -> subprocess.Popen[bytes]:
    with log.open("ab") as err:
        return subprocess.Popen(
            [sys.executable, "-m", "protocol_runner.cli", *args],
            stdout=subprocess.DEVNULL,
            stderr=err,
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
            start_new_session=True,
        )


def compare_with(reference: Path, session: Path) -> list[str]:
    """The differences `tools/compare_archives.py` finds between the two sessions' archives, less those a
    resume adds by design: its events (`session/events`: "interrupted", "resumed"), the calibration check
    a resume inside a set runs first (`calibration/<set>/resume_<n>`, only in the resumed archive), and the
    checksums of the attributes, which cover wall-clock values (`attribute_sha256`)."""
    spec = importlib.util.spec_from_file_location("compare_archives", COMPARE)
    assert spec is not None and spec.loader is not None
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    found: list[str] = tool.compare(reference / "archive.h5", session / "archive.h5", {"attribute_sha256"})
    return [
        line
        for line in found
        if "session/events" not in line
        and not (line.startswith("only in B: calibration/") and re.search(r"/resume_\d+(/|$)", line))
    ]


def group_members(pgid: int) -> list[str]:
    """The command lines of the live processes of group `pgid` (`ps`; a zombie, ended but not yet reaped
    by its parent, is not live)."""
    listing = subprocess.run(["ps", "-e", "-o", "pgid=,stat=,args="], capture_output=True, text=True).stdout
    rows = (line.split(None, 2) for line in listing.splitlines())
    return [r[2][:160] for r in rows if len(r) == 3 and r[0] == str(pgid) and not r[1].startswith("Z")]


def end_group(pgid: int) -> list[str]:
    """Wait up to ORPHAN_GRACE_S for the processes left in group `pgid` to end; kill those that do not and
    return what they were."""
    deadline = time.monotonic() + ORPHAN_GRACE_S
    while left := group_members(pgid):
        if time.monotonic() > deadline:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pgid, signal.SIGKILL)
            return left
        time.sleep(0.1)
    return []


def journal_lines(session: Path) -> list[dict[str, object]]:
    """The journal's complete records (a torn last line left aside)."""
    path = session / "journal.jsonl"
    if not path.exists():
        return []
    records = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True):
        if line.endswith("\n"):
            records.append(json.loads(line))
    return records


@dataclass
class Counts:
    runs: int = 0
    kills: int = 0
    finished_first: int = 0
    before_session: int = 0
    clean: int = 0
    redone_steps: int = 0
    redone_trials: int = 0
    lost: int = 0
    mismatches: int = 0
    hangs: int = 0
    failed_resumes: int = 0
    orphans: int = 0
    resume_s: list[float] = field(default_factory=list)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--kills", type=int, default=50, help="kills to make (default 50)")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds a resume may take")
    parser.add_argument("--seed", type=int, default=1, help="seed of the random moments")
    parser.add_argument("--only", default="1", help=f"the configurations of {PROTOCOL} to run")
    parser.add_argument(
        "--keep", action="store_true", help="keep the sessions of resumes that were not clean"
    )
    args = parser.parse_args()
    if os.name == "nt":
        print("POSIX only (process groups)")
        return 2
    run_args = [PROTOCOL, "--dry-run", "--seed", "7", "--only", args.only]
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="kill-loop-"))
    counts = Counts()
    try:
        reference = work / "reference"
        t0 = time.monotonic()
        code = cli(*run_args, "--session", str(reference), log=work / "reference.err").wait(timeout=900)
        span_s = time.monotonic() - t0
        if code != 0:
            print((work / "reference.err").read_text(errors="replace"))
            return 2
        expected = set(inspect_journal(reference / "journal.jsonl").units)
        print(
            f"uninterrupted run: {span_s:.1f} s, {len(expected)} steps; {args.kills} kills wanted", flush=True
        )
        while counts.kills < args.kills and counts.runs < 2 * args.kills:
            n = counts.runs
            counts.runs += 1
            session, log = work / f"s{n}", work / f"s{n}.err"
            delay_s = rng.uniform(0.2, span_s)
            proc = cli(*run_args, "--session", str(session), log=log)
            time.sleep(delay_s)
            if proc.poll() is not None:
                counts.finished_first += 1
                print(
                    f"try {n + 1:3d}: ended (exit {proc.returncode}) before the kill at {delay_s:5.2f} s",
                    flush=True,
                )
                shutil.rmtree(session, ignore_errors=True)
                continue
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            if proc.returncode != -signal.SIGKILL:  # it was exiting when the kill came: its exit stands
                counts.finished_first += 1
                print(f"try {n + 1:3d}: ended (exit {proc.returncode}) as the kill came at {delay_s:5.2f} s")
                shutil.rmtree(session, ignore_errors=True)
                continue
            counts.kills += 1
            left = end_group(proc.pid)
            if left:
                counts.orphans += 1
                print(f"    still running {ORPHAN_GRACE_S:g} s after the kill (killed): " + "; ".join(left))
            if not (session / "session.json").exists():  # killed while starting: no session to resume
                print(f"try {n + 1:3d}: killed at {delay_s:5.2f} s, before the session began", flush=True)
                counts.before_session += 1
                continue
            before = journal_lines(session)
            done = inspect_journal(session / "journal.jsonl").units if before else {}
            t_resume = time.monotonic()
            resumed = cli("--resume", str(session), log=log)
            problems: list[str] = []
            try:
                code = resumed.wait(timeout=args.timeout)
                counts.resume_s.append(time.monotonic() - t_resume)
            except subprocess.TimeoutExpired:
                os.killpg(resumed.pid, signal.SIGKILL)
                resumed.wait()
                counts.hangs += 1
                code = None
                problems.append("hung")
            if code is not None and code != 0:
                counts.failed_resumes += 1
                problems.append(f"resume exit {code}")
            end_group(resumed.pid)
            if code == 0:
                after = journal_lines(session)[len(before) :]
                again = sorted(
                    {str(r["step_id"]) for r in after if r.get("record") in ("unit", "invalidate")}
                    & set(done)
                )
                final = inspect_journal(session / "journal.jsonl").units
                changed = sorted(s for s in done if s in final and final[s].sha256 != done[s].sha256)
                lost = sorted(expected - set(final))
                counts.redone_steps += len(again)
                counts.redone_trials += sum(s.startswith("trial:") for s in again)
                counts.lost += len(lost)
                if again or changed:
                    problems.append(f"redone {again} (checksum changed: {changed})")
                if lost:
                    problems.append(f"lost {lost}")
                check = subprocess.run(
                    [sys.executable, "-m", "protocol_runner.cli", "--verify", str(session)],
                    capture_output=True,
                    text=True,
                )
                differences = compare_with(reference, session)
                if check.returncode != 0 or differences:
                    counts.mismatches += 1
                    problems.append(f"verify exit {check.returncode}, {len(differences)} differences")
                    problems.append((check.stderr + "\n".join(differences)).strip()[-2000:])
            took = f"{counts.resume_s[-1]:5.1f} s" if code is not None else "hung"
            said = "clean" if not problems else "NOT CLEAN: " + "; ".join(problems)
            print(
                f"try {n + 1:3d}: killed at {delay_s:5.2f} s after {len(done)} steps, resumed in {took}: {said}"
            )
            if problems:
                print("    " + "\n    ".join(log.read_text(errors="replace").strip().splitlines()[-20:]))
            sys.stdout.flush()
            if not problems:
                counts.clean += 1
            if not problems or not args.keep:
                shutil.rmtree(session, ignore_errors=True)
        c = counts
        print(
            f"runs: {c.runs}, kills: {c.kills} (before the session began: {c.before_session}; runs ended before "
            f"the kill: {c.finished_first}), "
            f"clean resumes: {c.clean}, redone steps: {c.redone_steps} (trials: {c.redone_trials}), "
            f"lost steps: {c.lost}, mismatches: {c.mismatches}, failed resumes: {c.failed_resumes}, "
            f"hangs: {c.hangs}, kills after which a process of the run (a worker, the fork server) still ran "
            f"{ORPHAN_GRACE_S:g} s later: {c.orphans}"
        )
        if c.resume_s:
            print(
                f"resume time: median {statistics.median(c.resume_s):.1f} s, longest {max(c.resume_s):.1f} s "
                f"(uninterrupted run {span_s:.1f} s)"
            )
        return 0 if c.clean + c.before_session == c.kills else 1
    finally:
        if not args.keep or counts.clean + counts.before_session == counts.kills:
            shutil.rmtree(work, ignore_errors=True)
        else:
            print(f"sessions kept in {work}")


if __name__ == "__main__":
    sys.exit(main())
