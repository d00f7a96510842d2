"""`run-protocol`: argument parsing and exit codes only; the work happens in the modules it calls.

Exit status: 0 done; 2 invalid input; 3 hardware unavailable; 4 stopped by a safety or
calibration check; 130 interrupted or disk full (resumable).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from . import __version__
from .errors import (
    EXIT_INTERRUPTED,
    EXIT_INVALID_INPUT,
    EXIT_OK,
    InvalidInput,
    UserError,
    file_system_refusal,
)
from .protocol.only import KeySelection

if TYPE_CHECKING:
    from .monitor.service import Monitor

DESCRIPTION = """\
Run a declarative test protocol for space-suit joint testing on the RSST robot.

modes:
  run-protocol PROTOCOL [--dry-run] [--session DIR] [--seed N] [--yes] [--only KEYS] [--monitor [HOST:]PORT]
      run a campaign; --dry-run rehearses it against the DAQ simulator in simulated time
  run-protocol --resume SESSION_DIR [--yes] [--force] [--monitor [HOST:]PORT]
      continue an interrupted session without redoing finished steps
  run-protocol --report SESSION_DIR|ARCHIVE.h5 [--output FILE] [--reprocess] [--export-mat DIR]
      (re)generate the HTML report from an archive alone
  run-protocol --export SESSION_DIR|ARCHIVE.h5 [--output DIR]
      write cycles.csv, trials.csv and configurations.csv (units in the column names)
  run-protocol --compare A B [--output FILE]
      compare two sessions or archives configuration by configuration (95 % Welch intervals)
  run-protocol --verify SESSION_DIR|ARCHIVE.h5
      check every dataset against its checksum; exit 2 naming each damaged one
  run-protocol --plan PROTOCOL [--json]
      print the expanded plan (steps in execution order with their stable ids)
  run-protocol --validate PROTOCOL
      check a protocol file and report every problem with file, line and field
  run-protocol --hardware-check [PROTOCOL]
      list the DAQ boards attached, blink them, and check the protocol's channels

PROTOCOL is a path, or a bare file name looked up in ./protocols/ and then among the protocols shipped
with the package, so `run-protocol knee_phase1.yaml --dry-run` works from any directory.
"""

EPILOG = """\
examples:
  run-protocol knee_phase1.yaml --dry-run --yes          full rehearsal: archive.h5 + report.html
  run-protocol knee_phase1.yaml --dry-run --only 4,5,6,7 just the friction configurations
  run-protocol knee_phase1.yaml --monitor 8765          watch it live at http://127.0.0.1:8765/
  run-protocol --plan knee_phase1.yaml --json > plan.json
  run-protocol --validate my_campaign.yaml
  run-protocol --resume sessions/knee_phase1-20261121T101500Z
  run-protocol --report sessions/knee_phase1-20261121T101500Z/archive.h5 --output report.html

exit status: 0 done, 2 invalid input (or a damaged archive), 3 hardware unavailable, 4 stopped by a
safety or calibration check, 130 interrupted or disk full (the session is resumable with --resume).
"""


_OPTIONS: tuple[tuple[str, str, str | None, str], ...] = (
    # (group, flag, metavar (None: a switch), help), in the order --help lists them
    ("mode", "--resume", "SESSION_DIR", "resume an interrupted session"),
    ("mode", "--report", "PATH", "regenerate the report of a session directory or archive"),
    ("mode", "--verify", "PATH", "check the checksums of a session directory's or archive's datasets"),
    ("mode", "--export", "PATH", "write tidy CSV tables of a session or archive"),
    ("mode", "--compare", "A B", "compare two sessions or archives (HTML + table)"),
    ("mode", "--plan", "PROTOCOL", "print the expanded plan of a protocol"),
    ("mode", "--validate", "PROTOCOL", "validate a protocol file"),
    ("mode", "--hardware-check", "PROTOCOL", "check the DAQ boards (and a protocol's channels)"),
    ("running", "--dry-run", None, "run against the DAQ simulator (simulated time)"),
    ("running", "--realtime", None, "with --dry-run: pace the simulator like the hardware"),
    ("running", "--session", "DIR", "session directory (default: sessions/<protocol>-<UTC time>/)"),
    ("running", "--seed", "SEED", "seed of the simulator's random draws (default 0)"),
    ("running", "--yes", None, "answer operator prompts automatically (checklists done)"),
    ("running", "--only", "KEYS", "run only these configuration keys, e.g. 4,5,6,7 or 12-14"),
    (
        "running",
        "--force",
        None,
        "with --resume: accept a changed protocol or referenced file, or a missing journal (recorded)",
    ),
    (
        "running",
        "--monitor",
        "[HOST:]PORT",
        "serve a live, read-only page of the session (default host 127.0.0.1; another host needs "
        "the token printed on the terminal)",
    ),
    ("output", "--json", None, "with --plan: print the plan as JSON (the contract shape)"),
    (
        "output",
        "--output",
        "FILE",
        "with --report/--compare: where to write the HTML; with --export: the directory",
    ),
    ("output", "--reprocess", None, "with --report: redo processing and fits from raw data"),
    ("output", "--protocol-file", "PROTOCOL", "with --reprocess: take processing settings from this file"),
    ("output", "--export-mat", "DIR", "with --report: write the archive as .mat files (docs/matlab.md)"),
)
_OPTION_EXTRAS: dict[str, dict[str, Any]] = {
    # what a row of _OPTIONS cannot say (these win over the row)
    "--compare": {"metavar": ("A", "B"), "nargs": 2},
    "--hardware-check": {"nargs": "?", "const": ""},
    # `run-protocol X.yaml --plan` reads as `run-protocol --plan X.yaml` (the protocol may come first)
    "--plan": {"nargs": "?", "const": ""},
    "--validate": {"nargs": "?", "const": ""},
    "--seed": {"type": int},
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="run-protocol",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("protocol", nargs="?", metavar="PROTOCOL", help="protocol file to run")
    groups = {
        "mode": parser.add_mutually_exclusive_group(),
        "running": parser.add_argument_group("running"),
        "output": parser.add_argument_group("output"),
    }
    for group, flag, metavar, help_text in _OPTIONS:
        kind: dict[str, Any] = {"action": "store_true"} if metavar is None else {"metavar": metavar}
        groups[group].add_argument(flag, help=help_text, **(kind | _OPTION_EXTRAS.get(flag, {})))
    parser.add_argument("--version", action="version", version=f"protocol-runner {__version__}")
    return parser


def parse_only(text: str | None) -> KeySelection | None:
    """`--only 4,5,6,7` or `--only 12-14,27` -> the keys and ranges (checked against the protocol later)."""
    return None if text is None else KeySelection.parse(text)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _ENDED_BY_A_FULL_DISK.clear()
    try:
        return _dispatch(parser, args)
    except UserError as exc:
        print(f"run-protocol: {exc.message}", file=sys.stderr)
        from .archive.diskfull import DiskFull

        if isinstance(exc, DiskFull):
            _ENDED_BY_A_FULL_DISK.set()
        return exc.exit_code
    except OSError as exc:
        from .archive.diskfull import is_disk_full

        if not is_disk_full(exc):
            refusal = file_system_refusal(exc)
            if refusal is not None:  # the file system said no: not a bug of ours
                print(f"run-protocol: {refusal}", file=sys.stderr)
                return EXIT_INVALID_INPUT
            raise
        print(
            f"run-protocol: disk full ({exc.filename or exc.strerror or exc}): nothing finished is lost. Free "
            "some space, then run the command again (a session continues with run-protocol --resume DIR)",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    except KeyboardInterrupt:
        print("run-protocol: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _dispatch(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    if args.monitor is not None and any(
        m is not None
        for m in (args.plan, args.validate, args.report, args.hardware_check, args.export, args.compare)
    ):
        raise InvalidInput("--monitor watches a session: use it with a PROTOCOL to run or with --resume")
    if args.plan is not None:
        args.plan = _mode_protocol("--plan", args.plan, args.protocol)
        return _cmd_plan(args)
    if args.validate is not None:
        args.validate = _mode_protocol("--validate", args.validate, args.protocol)
        return _cmd_validate(args)
    if args.hardware_check is not None:
        from .commands import hardware_check

        return hardware_check(args.hardware_check or None)
    if args.report is not None:
        from .commands import report

        return report(
            Path(args.report),
            output=Path(args.output) if args.output else None,
            reprocess=args.reprocess,
            protocol_file=args.protocol_file,
            export_mat=Path(args.export_mat) if args.export_mat else None,
        )
    if args.export is not None or args.compare is not None:
        from .commands import compare, export

        output = Path(args.output) if args.output else None
        if args.export is not None:
            return export(Path(args.export), output)
        return compare(Path(args.compare[0]), Path(args.compare[1]), output)
    if args.verify is not None:
        from .commands import verify

        return verify(Path(args.verify))
    if args.monitor is not None and (args.resume is not None or args.protocol is not None):
        from .monitor.service import Monitor

        with Monitor.open(args.monitor, say=lambda text: print(text, file=sys.stderr, flush=True)) as live:
            return _run_or_resume(parser, args, live)
    return _run_or_resume(parser, args, None)


def _run_or_resume(parser: argparse.ArgumentParser, args: argparse.Namespace, monitor: Monitor | None) -> int:
    if args.resume is not None:
        from .commands import resume

        if args.protocol is not None:
            raise InvalidInput("--resume continues a session with its own stored protocol: drop PROTOCOL")
        return resume(
            Path(args.resume),
            yes=args.yes,
            force=args.force,
            realtime=args.realtime,
            seed=args.seed,
            only=parse_only(args.only),
            monitor=monitor,
        )
    if args.protocol is None:
        parser.print_usage(sys.stderr)
        print(
            "run-protocol: give a PROTOCOL to run, or one of --plan, --validate, --resume, --report, --verify",
            file=sys.stderr,
        )
        return EXIT_INVALID_INPUT
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise InvalidInput(f"--seed: {args.seed} is out of range (0 to 2**63 - 1)")
    from .commands import run

    return run(
        args.protocol,
        dry_run=args.dry_run,
        session=Path(args.session) if args.session else None,
        seed=args.seed,
        yes=args.yes,
        only=parse_only(args.only),
        realtime=args.realtime,
        monitor=monitor,
    )


def _mode_protocol(flag: str, given: str, positional: str | None) -> str:
    """The protocol of `--plan`/`--validate`: written after the flag or (`run-protocol X.yaml --plan`) before it."""
    if given and positional:
        raise InvalidInput(f"{flag} {given}: a second protocol {positional} was also given; name one")
    if not (given or positional):
        raise InvalidInput(f"{flag} needs a PROTOCOL: run-protocol {flag} my_campaign.yaml")
    return given or str(positional)


def _cmd_validate(args: argparse.Namespace) -> int:
    from .preflight import preflight, preflight_warnings
    from .protocol.loader import find_protocol, load_protocol
    from .protocol.plan_table import robot_time_text

    path = find_protocol(args.validate)
    loaded = load_protocol(path, display_name=args.validate if Path(args.validate).exists() else str(path))
    plan = preflight(loaded)  # exactly the run's checks before it creates a session
    for warning in preflight_warnings(loaded, plan):
        print(warning, file=sys.stderr)
    trials = sum(1 for s in plan.steps if s.kind == "trial")
    n_cfg = len(loaded.protocol.configurations())
    print(
        f"{path}: valid. {loaded.protocol.name}: {len(loaded.protocol.sets)} sets, {n_cfg} configurations, "
        f"{trials} trials, {len(plan)} steps, about {robot_time_text(plan.robot_time_s)} of robot time. "
        f"sha256 {loaded.sha256[:16]}..."
    )
    return EXIT_OK


def _cmd_plan(args: argparse.Namespace) -> int:
    from .preflight import preflight, preflight_warnings
    from .protocol.loader import find_protocol, load_protocol
    from .protocol.plan_table import format_plan_table

    path = find_protocol(args.plan)
    loaded = load_protocol(path, display_name=args.plan if Path(args.plan).exists() else str(path))
    plan = preflight(loaded, only=parse_only(args.only))
    for warning in preflight_warnings(loaded, plan):
        print(warning, file=sys.stderr)
    if args.json:
        sys.stdout.write(plan.dumps() + "\n")
    else:
        sys.stdout.write(format_plan_table(plan) + "\n")
    return EXIT_OK


def entry() -> None:
    """The `run-protocol` command (and `python -m protocol_runner.cli`): `main` on the process's arguments,
    its status the process's exit status. Callers in their own process use `main(argv)`.

    After a session stopped on a full disk, HDF5 may still hold a file whose close failed for lack of
    space, and the interpreter's teardown closing it again crashes the process (a segmentation fault, exit
    139 instead of 130: `--only 15,16,17` on a 3 MB file system). So the process then ends at once, its
    output and log flushed, as after a kill, which loses nothing: every finished unit is on disk and
    journaled, and a temporary file is removed or redone by the resume (docs/session.md)."""
    one_blas_thread()
    code = main()
    if _ENDED_BY_A_FULL_DISK.is_set():
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


_ENDED_BY_A_FULL_DISK = threading.Event()  # set by `main` when a session stopped on a full disk


def one_blas_thread() -> None:
    """Have OpenBLAS start with one thread in this process and the processes it starts (the analysis
    workers), unless the environment already says how many (`OPENBLAS_NUM_THREADS` is kept as set).

    numpy and scipy each load their own OpenBLAS, which starts a pool of threads that spin, waiting for
    work, for about 0.1 s of CPU each after it starts and after every fork: 0.2 s at the session's start-up
    and more in the fork server and each worker, on a two-core machine whose other core the workers need.
    Nothing of this program's gains from more: the session's own BLAS calls are small, and the model fits
    hold BLAS at one thread while they run anyway (threadpoolctl, models/bouc_wen/threads.py). It is read
    by OpenBLAS when it loads, so it is set here, before anything imports numpy (checked by a test); a
    program calling `main(argv)` keeps its own setting."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


if __name__ == "__main__":  # pragma: no cover
    entry()
