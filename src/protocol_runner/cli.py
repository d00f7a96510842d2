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

from .errors import (
    EXIT_INTERRUPTED,
    EXIT_INVALID_INPUT,
    EXIT_OK,
    InvalidInput,
    UserError,
    causes,
    file_system_refusal,
)
from .protocol.only import KeySelection
from .session.signals import on_the_way_out
from .session.streams import say

if TYPE_CHECKING:
    from .monitor.service import Monitor

DESCRIPTION = """\
Run a declarative test protocol for space-suit joint testing on the RSST robot.

modes:
  run-protocol PROTOCOL --dry-run [--seed N] [--only KEYS] [--session DIR] [--realtime] [--monitor [HOST:]PORT]
      rehearse a campaign against the DAQ simulator in simulated time (prompts are answered automatically)
  run-protocol PROTOCOL [--yes] [--only KEYS] [--session DIR] [--monitor [HOST:]PORT]
      run a campaign on the rig's USB boards; --yes answers the operator checklists
  run-protocol --resume SESSION_DIR [--yes] [--force] [--monitor [HOST:]PORT]
      continue an interrupted session without redoing finished steps
  run-protocol --report SESSION_DIR|ARCHIVE.h5 [--output FILE] [--reprocess [--protocol-file P]] [--export-mat DIR]
      (re)generate the HTML report from an archive alone
  run-protocol --export SESSION_DIR|ARCHIVE.h5 [--output DIR] [--only KEYS]
      write cycles.csv, trials.csv and configurations.csv (units in the column names)
  run-protocol --compare A B [--output FILE]
      compare two sessions or archives configuration by configuration (95 % Welch intervals)
  run-protocol --verify SESSION_DIR|ARCHIVE.h5
      check every dataset against its checksum; exit 2 naming each damaged one
  run-protocol --plan PROTOCOL [--json] [--only KEYS]
      print the expanded plan (steps in execution order with their stable ids)
  run-protocol --plan PROTOCOL --power SESSION|--power-cv CV [--power-effect FRACTION]
      trials per configuration each expectation needs for 80 % power, and those the plan cannot decide
  run-protocol --validate PROTOCOL
      check a protocol file and report every problem with file, line and field
  run-protocol --hardware-check [PROTOCOL]
      list the DAQ boards attached, blink them, and check the protocol's channels
  run-protocol --schema
      print the protocol file's JSON Schema (for an editor's completion and checking)

PROTOCOL is a path, or a bare file name looked up in ./protocols/ and then among the protocols shipped
with the package, so `run-protocol knee_phase1.yaml --dry-run` works from any directory. A flag that does
not apply to the mode is refused (exit 2).
"""

EPILOG = """\
examples:
  run-protocol knee_phase1.yaml --dry-run --session sessions/knee   full rehearsal: archive.h5 + report.html
  run-protocol knee_phase1.yaml --dry-run --only 4,5,6,7            just the friction configurations
  run-protocol knee_phase1.yaml --dry-run --monitor 8765            watch it live at http://127.0.0.1:8765/
  run-protocol --plan knee_phase1.yaml --json > plan.json
  run-protocol --plan knee_phase1.yaml --power sessions/knee        trials each expectation needs
  run-protocol --validate knee_phase1.yaml
  run-protocol --resume sessions/knee                                continue it after an interruption
  run-protocol --report sessions/knee/archive.h5 --output report.html

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
    ("mode", "--schema", None, "print the protocol file's JSON Schema (for editors)"),
    ("running", "--dry-run", None, "run against the DAQ simulator (simulated time)"),
    ("running", "--realtime", None, "with --dry-run: pace the simulator like the hardware"),
    ("running", "--session", "DIR", "session directory (default: sessions/<protocol>-<UTC time>/)"),
    ("running", "--seed", "SEED", "seed of the simulator's random draws (default 0)"),
    ("running", "--yes", None, "on the rig or with --resume: answer operator prompts automatically"),
    (
        "running",
        "--only",
        "KEYS",
        "run (or with --plan/--export: show) only these configuration keys, e.g. 4,5,6,7 or 12-14",
    ),
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
    (
        "output",
        "--power",
        "SESSION",
        "with --plan: the trials per configuration each expectation needs for 80 %% power, from the "
        "between-trial spread in SESSION (a session directory or archive of the same protocol)",
    ),
    (
        "output",
        "--power-cv",
        "CV",
        "with --plan, instead of --power: assume this between-trial coefficient of variation in every "
        "configuration (e.g. 0.05)",
    ),
    (
        "output",
        "--power-effect",
        "FRACTION",
        "with --power or --power-cv: plan each difference statement for a true difference of this fraction "
        "of its configurations' level (with --power-cv by default 0.05)",
    ),
)

_OPTION_EXTRAS: dict[str, dict[str, Any]] = {
    # what a row of _OPTIONS cannot say (these win over the row)
    "--compare": {"metavar": ("A", "B"), "nargs": 2},
    "--hardware-check": {"nargs": "?", "const": ""},
    # `run-protocol X.yaml --plan` reads as `run-protocol --plan X.yaml` (the protocol may come first)
    "--plan": {"nargs": "?", "const": ""},
    "--validate": {"nargs": "?", "const": ""},
    "--seed": {"type": int},
    "--power-cv": {"type": float},
    "--power-effect": {"type": float},
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
    from . import __version__  # here: reading the package's metadata takes a moment (see __init__)

    parser.add_argument("--version", action="version", version=f"protocol-runner {__version__}")
    return parser


def parse_only(text: str | None) -> KeySelection | None:
    """`--only 4,5,6,7` or `--only 12-14,27` -> the keys and ranges (checked against the protocol later)."""
    return None if text is None else KeySelection.parse(text)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _ENDED_BY_A_FULL_DISK.clear()
    _ENDED_BY_AN_INTERRUPT.clear()
    try:
        return _dispatch(parser, args)
    except UserError as exc:
        say(f"run-protocol: {exc.message}")
        from .archive.diskfull import DiskFull

        if isinstance(exc, DiskFull):
            _ENDED_BY_A_FULL_DISK.set()
        return exc.exit_code
    except OSError as exc:
        from .archive.diskfull import is_disk_full

        if not is_disk_full(exc):
            refusal = file_system_refusal(exc)
            if refusal is not None:  # the file system said no: not a bug of ours
                say(f"run-protocol: {refusal}")
                return EXIT_INVALID_INPUT
            raise
        say(
            f"run-protocol: disk full ({exc.filename or exc.strerror or exc}): nothing finished is lost. Free "
            "some space, then run the command again (a session continues with run-protocol --resume DIR)"
        )
        return EXIT_INTERRUPTED
    except BaseException as exc:  # a Ctrl-C, also one inside an import ("initialization failed")
        if not any(isinstance(e, KeyboardInterrupt) for e in causes(exc)):
            raise
        on_the_way_out()
        _ENDED_BY_AN_INTERRUPT.set()
        say("run-protocol: interrupted")
        return EXIT_INTERRUPTED


RUN = "a run"
"""The mode of `run-protocol PROTOCOL [--dry-run]` (no mode flag) in `FLAG_MODES` and messages."""

MODES: tuple[str, ...] = tuple(flag for group, flag, _, _ in _OPTIONS if group == "mode")
"""The mode flags, in the order --help lists them; without one, PROTOCOL is run."""

FLAG_MODES: dict[str, tuple[str, ...]] = {
    # the modes each non-mode flag (and PROTOCOL) applies to; anywhere else it is refused (exit 2)
    "PROTOCOL": (RUN, "--plan", "--validate", "--hardware-check"),
    "--dry-run": (RUN,),
    "--realtime": (RUN,),
    "--session": (RUN,),
    "--seed": (RUN, "--resume"),
    "--yes": (RUN, "--resume"),
    "--only": (RUN, "--resume", "--plan", "--export"),
    "--force": ("--resume",),
    "--monitor": (RUN, "--resume"),
    "--json": ("--plan",),
    "--output": ("--report", "--export", "--compare"),
    "--reprocess": ("--report",),
    "--protocol-file": ("--report",),
    "--export-mat": ("--report",),
    "--power": ("--plan",),
    "--power-cv": ("--plan",),
    "--power-effect": ("--plan",),
}


_WHY = {"--monitor": "watches a session", "--json": "is the format of the plan"}


def _mode(args: argparse.Namespace) -> str:
    """The mode flag given (argparse lets at most one through), or `RUN`."""
    for flag in MODES:
        value = getattr(args, _dest(flag))
        if value is not None and value is not False:
            return flag
    return RUN


def _dest(flag: str) -> str:
    return "protocol" if flag == "PROTOCOL" else flag.lstrip("-").replace("-", "_")


def check_flags(args: argparse.Namespace) -> str:
    """The mode of `args`; `InvalidInput` naming the flag and the mode when a flag given does not apply to
    it (a flag silently ignored would let the operator believe it did something)."""
    mode = _mode(args)
    where = "a run (PROTOCOL)" if mode == RUN else mode
    for flag, modes in FLAG_MODES.items():
        value = getattr(args, _dest(flag))
        if value is None or value is False or mode in modes:
            continue
        names = ["a run" if m == RUN else m for m in modes]
        goes = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"
        if flag == "PROTOCOL":
            own = " (it continues a session with its own stored protocol)" if mode == "--resume" else ""
            raise InvalidInput(f"PROTOCOL {value} does not apply to {where}{own}: drop PROTOCOL")
        why = _WHY.get(flag)
        raise InvalidInput(
            f"{flag} {why}, so it does not apply to {where}: use it with {goes}"
            if why
            else f"{flag} does not apply to {where}: it goes with {goes}"
        )
    if mode == RUN and args.dry_run and args.yes:
        raise InvalidInput(
            "--yes does not apply to a dry run: a dry run answers the operator prompts itself; drop --yes"
        )
    if mode == RUN and args.realtime and not args.dry_run:
        raise InvalidInput("--realtime paces the simulator: use it with --dry-run")
    if args.protocol_file is not None and not args.reprocess:
        raise InvalidInput("--protocol-file gives the settings --reprocess uses: add --reprocess")
    # `--power SESSION` or `--power-cv CV` (one of them), `--power-effect` only with one, no `--json`
    if args.power is not None and args.power_cv is not None:
        raise InvalidInput(
            "--power and --power-cv are two sources of the between-trial spread: give one (--power SESSION "
            "measures it, --power-cv assumes it)"
        )
    planning = args.power is not None or args.power_cv is not None
    if args.power_effect is not None and not planning:
        raise InvalidInput(
            "--power-effect is the effect a trial count is planned for: add --power or --power-cv"
        )
    if planning and args.json:
        raise InvalidInput("--json is the format of the plan, not of the trial counts: drop --json")
    for flag, value, most in (
        ("--power-cv", args.power_cv, 1.0),
        ("--power-effect", args.power_effect, 10.0),
    ):
        if value is not None and not 0.0 < value <= most:
            raise InvalidInput(
                f"{flag} {value:g}: give a fraction of the mean, above 0 and at most {most:g} (0.05 for 5 %)"
            )
    return mode


def _dispatch(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    mode = check_flags(args)
    if mode == "--schema":
        from .protocol.schema import protocol_json_schema_text

        sys.stdout.write(protocol_json_schema_text())
        return EXIT_OK
    if mode == "--plan":
        args.plan = _mode_protocol("--plan", args.plan, args.protocol)
        if args.power is None and args.power_cv is None:
            from .commands import preflighted
            from .protocol.plan_table import format_plan_table

            _, plan = preflighted(args.plan, parse_only(args.only))
            sys.stdout.write((plan.dumps() if args.json else format_plan_table(plan)) + "\n")
            return EXIT_OK
    if mode == "--validate":
        args.validate = _mode_protocol("--validate", args.validate, args.protocol)
        return _cmd_validate(args)
    from . import commands  # the other modes' actions

    output = Path(args.output) if args.output else None
    if mode == "--plan":
        return commands.power_plan(
            args.plan,
            session=Path(args.power) if args.power is not None else None,
            cv=args.power_cv,
            effect_ratio=args.power_effect,
            only=parse_only(args.only),
        )
    if mode == "--hardware-check":
        if args.hardware_check and args.protocol:
            _mode_protocol("--hardware-check", args.hardware_check, args.protocol)  # refuses two protocols
        return commands.hardware_check(args.hardware_check or args.protocol or None)
    if mode == "--report":
        return commands.report(
            Path(args.report),
            output=output,
            reprocess=args.reprocess,
            protocol_file=args.protocol_file,
            export_mat=Path(args.export_mat) if args.export_mat else None,
        )
    if mode == "--export":
        return commands.export(Path(args.export), output, only=parse_only(args.only))
    if mode == "--compare":
        return commands.compare(Path(args.compare[0]), Path(args.compare[1]), output)
    if mode == "--verify":
        return commands.verify(Path(args.verify))
    if args.monitor is not None and (args.resume is not None or args.protocol is not None):
        from .monitor.service import Monitor

        with Monitor.open(args.monitor, say=say) as live:
            return _run_or_resume(parser, args, live)
    return _run_or_resume(parser, args, None)


def _run_or_resume(parser: argparse.ArgumentParser, args: argparse.Namespace, monitor: Monitor | None) -> int:
    from . import commands

    if args.resume is not None:
        return commands.resume(
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
        print(f"run-protocol: give a PROTOCOL to run, or one of {', '.join(MODES)}", file=sys.stderr)
        return EXIT_INVALID_INPUT
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise InvalidInput(f"--seed: {args.seed} is out of range (0 to 2**63 - 1)")
    return commands.run(
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
    from .commands import preflighted
    from .protocol.plan_table import robot_time_text
    from .protocol.validate import unused_trajectories
    from .protocol.wording import counted

    loaded, plan = preflighted(args.validate)
    p = loaded.protocol
    trials = sum(1 for s in plan.steps if s.kind == "trial")
    unused = unused_trajectories(p)
    declared = (  # checked all the same (protocol/validate.py); may be a set forgotten
        f"Declared but used by no configuration: {counted(len(unused), 'trajectory', 'trajectories')} "
        f"({', '.join(unused)}). "
        if unused
        else ""
    )
    print(
        f"{loaded.path}: valid. {p.name}: {counted(len(p.sets), 'set')}, "
        f"{counted(len(p.configurations()), 'configuration')}, {counted(trials, 'trial')}, "
        f"{counted(len(plan), 'step')}, about {robot_time_text(plan.robot_time_s)} of robot time. "
        f"{declared}sha256 {loaded.sha256[:16]}..."
    )
    return EXIT_OK


def entry() -> None:
    """The `run-protocol` command: `main` on the process's arguments, its status the exit status.

    After a full disk or a Ctrl-C the process ends at once (`os._exit`), its output and log flushed, which
    loses nothing (every finished unit is on disk and journaled): the interpreter's teardown could close
    again an HDF5 file whose close failed (a segmentation fault), wait for ever on a worker pool the
    interrupt broke, or end by the signal itself (exit -2). Once `main` has returned, SIGINT is ignored."""
    one_blas_thread()
    from .session.signals import exit_at_once_after_second_sigint, stopped_at_once
    from .session.streams import flush_standard_streams, reopen_missing_standard_streams

    reopen_missing_standard_streams()  # `2>&-`: the null device, not the next file opened, as descriptor 2
    exit_at_once_after_second_sigint()
    try:
        code = main()
    except KeyboardInterrupt:  # a Ctrl-C in the instant `main` returned
        code = EXIT_INTERRUPTED
        _ENDED_BY_AN_INTERRUPT.set()
    on_the_way_out()  # the exit status is decided: a Ctrl-C during the teardown is ignored from here on
    flush_standard_streams()  # a pipe whose reader ended: no "Exception ignored" at exit
    if _ENDED_BY_A_FULL_DISK.is_set() or _ENDED_BY_AN_INTERRUPT.is_set() or stopped_at_once():
        logging.shutdown()
        os._exit(code)
    sys.exit(code)


_ENDED_BY_A_FULL_DISK = threading.Event()  # set by `main` when a session stopped on a full disk
_ENDED_BY_AN_INTERRUPT = threading.Event()  # set when a Ctrl-C raised KeyboardInterrupt in this process


def one_blas_thread() -> None:
    """Have OpenBLAS start with one thread in this process and the analysis workers, unless
    `OPENBLAS_NUM_THREADS` is set: its idle threads spin after every start and fork, and nothing here gains
    from more. Set before anything imports numpy; a program calling `main(argv)` keeps its own."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


if __name__ == "__main__":  # pragma: no cover
    entry()
