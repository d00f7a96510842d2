"""The CLI's actions beyond planning: run, resume, report, verify, hardware check.

Each returns the process exit status; user mistakes raise `UserError` subclasses (the CLI prints them).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import EXIT_HARDWARE_UNAVAILABLE, EXIT_OK, InvalidInput
from .events import NULL_PUBLISHER, Publisher
from .session.streams import say

if TYPE_CHECKING:
    from collections.abc import Iterable, Iterator

    from .monitor.service import Monitor
    from .protocol.loaded import LoadedProtocol
    from .protocol.only import KeySelection
    from .protocol.plan_steps import Plan
    from .session.runner import RunResult
    from .session.setup import SessionInfo
    from .steps.context import Bench
    from .steps.operator import Operator


def _result(message: str) -> None:
    """The command's outcome, on standard output (progress and prompts are on standard error), so that
    `run-protocol ... > out` keeps the line naming the archive and the report."""
    say(message, stdout=True)


def load_named(name: str) -> LoadedProtocol:
    """The protocol file `name` (a path, or a bare file name looked up in ./protocols/ and then among the
    shipped protocols), loaded and checked."""
    from .protocol.loader import find_protocol, load_protocol

    path = find_protocol(name)
    return load_protocol(path, display_name=name if Path(name).exists() else str(path))


def preflighted(name: str, only: KeySelection | None = None) -> tuple[LoadedProtocol, Plan]:
    """The protocol `name` loaded and checked exactly as a run checks it before it creates a session (its
    warnings printed on standard error), with its plan."""
    from .preflight import preflight_warnings
    from .protocol.plan import expand

    loaded = load_named(name)
    plan = expand(loaded, only=only)
    for warning in preflight_warnings(loaded, plan):
        print(warning, file=sys.stderr)
    return loaded, plan


def run(protocol: str, **options: Any) -> int:
    """`run-protocol PROTOCOL`: `run_loaded` on the protocol file `protocol` (`options` are its own)."""
    result = run_loaded(load_named(protocol), **options)
    _result(f"done: {result.archive}" + (f" and {result.report}" if result.report else ""))
    return EXIT_OK


def run_loaded(
    loaded: LoadedProtocol,
    *,
    dry_run: bool,
    session: Path | None,
    seed: int | None,
    yes: bool,
    only: KeySelection | Iterable[int] | None,
    realtime: bool,
    quiet: bool = False,
    monitor: Monitor | None = None,
) -> RunResult:
    """Run (or with `dry_run` rehearse) a loaded protocol into a new session directory (`session`, or
    `sessions/<name>-<UTC time>/`): the run behind `run-protocol PROTOCOL`, its outcome returned."""
    from .preflight import preflight_warnings
    from .protocol.plan import expand
    from .protocol.plan_table import robot_time_text
    from .protocol.wording import counted
    from .session.runner import Runner
    from .session.setup import create_session, created_session_protocol, default_session_dir

    planned = expand(loaded, only=only)  # everything --validate checks, before anything is created
    for warning in preflight_warnings(loaded, planned):
        say(warning)
    if realtime and not dry_run:
        raise InvalidInput("--realtime paces the simulator: use it with --dry-run")
    if dry_run:
        operator = _operator(True)
    else:
        from .session.rigs import HardwareBench

        hardware = HardwareBench(loaded)  # exit 3 with a plain message when the boards are absent
        try:
            operator = _operator(yes)  # one that cannot ask (no terminal, no --yes): refused before creating
        except BaseException:
            hardware.close()
            raise
    directory = session or default_session_dir(loaded.protocol.name)
    info = create_session(
        directory,
        loaded,
        mode="dry-run" if dry_run else "hardware",
        seed=0 if seed is None else seed,
        only=planned.only,
        realtime=realtime,
    )
    stored, plan = created_session_protocol(directory, info, loaded), planned  # not read again
    bench = _bench(stored, info) if dry_run else hardware
    if not quiet:
        say(
            f"session {directory}: {loaded.protocol.name}, {counted(len(plan), 'step')}, about "
            f"{robot_time_text(plan.robot_time_s)} of robot motion ({info.mode}, seed {info.seed})"
        )
        if dry_run:
            from .numba_cache import cache_enabled, will_compile

            if will_compile():
                when = "first run only" if cache_enabled() else "in every run: no cache"
                say(f"compiling the simulator's kernels ({when})...")
    publisher: Publisher = NULL_PUBLISHER
    if monitor is not None:
        publisher, operator = monitor.attach(directory, info, plan, bench, operator)
    runner = Runner(directory, info, stored, plan, bench, operator, quiet=quiet, publisher=publisher)
    return runner.run()


def _bench(loaded: LoadedProtocol, info: SessionInfo) -> Bench:
    if info.mode == "dry-run":
        from .session.rigs import SimulatedBench

        return SimulatedBench(loaded, seed=info.seed, realtime=info.realtime)
    from .session.rigs import HardwareBench

    return HardwareBench(loaded)


def _operator(automatic: bool) -> Operator:
    from .session.operator import AutoOperator, ConsoleOperator

    return AutoOperator() if automatic else ConsoleOperator()


def resume(
    session_dir: Path,
    *,
    yes: bool,
    force: bool,
    realtime: bool,
    quiet: bool = False,
    seed: int | None = None,
    only: KeySelection | None = None,
    monitor: Monitor | None = None,
) -> int:
    from .protocol.wording import counted
    from .session.lock import refuse_session_links
    from .session.resume_checks import check_resume_arguments, resume_preflight
    from .session.runner import Runner
    from .session.setup import load_session_protocol, read_session_info

    info = read_session_info(session_dir)
    refuse_session_links(session_dir)  # before anything reads or deletes in it
    check_resume_arguments(info, seed=seed, only=only)
    loaded, plan, changed = load_session_protocol(session_dir, info, force=force)
    complete = resume_preflight(session_dir, plan, force=force, info=info)
    if complete is not None:
        say(complete)
        return EXIT_OK
    bench = _bench(loaded, info)
    operator = _operator(info.mode == "dry-run" or yes)
    publisher: Publisher = NULL_PUBLISHER
    if monitor is not None:
        publisher, operator = monitor.attach(session_dir, info, plan, bench, operator, resumed=True)
    say(f"resuming {session_dir}: {info.protocol_name} ({info.mode}, seed {info.seed})")
    result = Runner(
        session_dir,
        info,
        loaded,
        plan,
        bench,
        operator,
        resumed=True,
        protocol_changed=changed,
        quiet=quiet,
        publisher=publisher,
    ).run()
    rechecks = f", {counted(result.rechecks, 'calibration re-check')}" if result.rechecks else ""
    _result(
        f"done: {counted(result.steps_run, 'step')} run, {result.steps_skipped} already complete{rechecks}; "
        f"{result.archive}" + (f" and {result.report}" if result.report else "")
    )
    return EXIT_OK


def report(
    path: Path,
    *,
    output: Path | None,
    reprocess: bool,
    protocol_file: str | None,
    export_mat: Path | None,
) -> int:
    _html_output(output)
    with _session_held(path):
        from .report.render import generate_report

        archive = _archive_of(path, locked=True)
        if not reprocess:
            _export_mat(archive, export_mat)
            _result(f"report: {generate_report(archive, output)}")
            return EXIT_OK
        from .archive.reprocess import reprocess_archive
        from .report.evaluate import record_verdicts
        from .report.load import load_report_data
        from .report.predictions import record_predictions
        from .report.render import render_with_predictions
        from .session.workers import analysis_pool

        with analysis_pool() as pool:
            archive = reprocess_archive(archive, protocol_file=protocol_file, pool=pool)
        # read once, for the verdicts, the predictions and the report (which reads neither /expectations nor
        # /predictions: it decides them again from the data). Its datasets are not checked again: the archive
        # it was made from has just been checked, its bytes copied, and this process wrote everything new
        data = load_report_data(archive, verify=False)
        record_verdicts(archive, data)  # the verdicts follow the reprocessed data
        _result(f"reprocessed archive: {archive}")
        out = render_with_predictions(  # the predictions are recorded too, before the page is written
            data, output or archive.with_suffix(".html"), record=lambda m: record_predictions(archive, m)
        )
        _export_mat(archive, export_mat)
        _result(f"report: {out}")
        return EXIT_OK


def _export_mat(archive: Path, export_mat: Path | None) -> None:
    if export_mat is not None:
        from .archive.export import export_mat as do_export

        files = do_export(archive, export_mat)
        _result(f"wrote {len(files)} .mat files to {export_mat}")


def verify(path: Path) -> int:
    """`--verify`: every dataset of an archive (or of a session's archive and units) against its checksum."""
    from .archive.verify import verify_path

    verdict = verify_path(path)
    verdict.problems.extend(_journaled_units_missing(Path(path)))
    for line in verdict.lines:
        print(line)
    if verdict.problems:
        shown = verdict.problems[:20]
        more = len(verdict.problems) - len(shown)
        raise InvalidInput(
            f"{len(verdict.problems)} problem(s) found:\n  "
            + "\n  ".join(shown)
            + (f"\n  ... and {more} more" if more else "")
        )
    return EXIT_OK


def _journaled_units_missing(session_dir: Path) -> list[str]:
    """For a session directory: each unit its journal records as complete whose file is gone (a resume
    redoes its step; the archive, if made before, still holds it)."""
    from .session.journal import inspect_journal

    journal = session_dir / "journal.jsonl"
    if not session_dir.is_dir() or not journal.exists():
        return []
    try:
        recorded = inspect_journal(journal).units
    except OSError as exc:
        return [f"{journal}: cannot be read as this session's journal ({exc})"]
    units = session_dir / "units"
    return [
        f"{units / record.file}: journaled as the complete unit of {step_id} but missing (a resume redoes the step)"
        for step_id, record in sorted(recorded.items())
        if not (units / record.file).is_file()
    ]


def _html_output(path: Path | None) -> None:
    """Refuse an `--output` that would overwrite a file which is not an HTML page (an archive or a journal
    given by mistake), or is not a regular file (archive/outputs.py)."""
    if path is None:
        return
    from .archive.outputs import refuse_special

    refuse_special(path, "--output")
    if not path.is_file():
        return
    try:
        with path.open("rb") as f:
            head = f.read(512).lstrip().lower()
    except OSError:
        return  # the write says why
    if not (head.startswith(b"<!doctype html") or head.startswith(b"<html")) and path.stat().st_size > 0:
        raise InvalidInput(
            f"--output {path}: exists and is not an HTML page (an archive, a unit, a journal?); it is not "
            "overwritten. Give a new file name, or the path of an earlier report"
        )


@contextlib.contextmanager
def _session_held(path: Path) -> Iterator[None]:
    """Hold the lock of the session that `path` (a session directory, or an archive in one) belongs to, so
    that a report is never rendered from an archive a running `--resume` is about to replace: while a run
    holds the session, `--report` is refused (exit 2, naming its PID), and the reverse. A session folder
    where no lock can be created (read-only media) is read without one: nothing can be writing to it."""
    from .session.lock import session_lock

    folder = path if path.is_dir() else path.parent
    with contextlib.ExitStack() as held:
        if (folder / "session.json").is_file():  # else an archive on its own
            with contextlib.suppress(OSError):  # no lock can be made (read-only): none can be held
                held.enter_context(session_lock(folder))
        yield


def _archive_of(path: Path, *, locked: bool = False) -> Path:
    """An archive path, or a session directory (consolidated first if it has none yet; `locked`: the caller
    holds the session's lock)."""
    if path.is_dir():
        candidate = path / "archive.h5"
        if candidate.is_file():
            return candidate
        if (path / "session.json").is_file():
            return _consolidate_unfinished(path, locked=locked)
        raise InvalidInput(f"{path}: neither an archive.h5 nor a session directory")
    if not path.exists():
        raise InvalidInput(f"{path}: no such archive or session directory")
    return path


def _consolidate_unfinished(session_dir: Path, *, locked: bool = False) -> Path:
    from .session.lock import session_lock
    from .session.runner import Runner
    from .session.setup import load_session_protocol, read_session_info

    # a resume may have finished meanwhile: look again, holding the lock
    with contextlib.nullcontext() if locked else session_lock(session_dir):
        archive = session_dir / "archive.h5"
        if archive.is_file():
            return archive
        info = read_session_info(session_dir)
        loaded, plan, _ = load_session_protocol(session_dir, info, force=True)
        # no bench, no operator: no step runs, the archive is only assembled
        runner = Runner(session_dir, info, loaded, plan, None, None, quiet=True)  # type: ignore[arg-type]
        return runner.consolidate("incomplete")


def hardware_check(protocol: str | None) -> int:
    from .hardware.discovery import format_report
    from .hardware.discovery import hardware_check as check
    from .protocol.rig_file import output_timing, parse_rig_text, shipped_rig

    required = None
    rig_file = shipped_rig("rsst")  # its output report time is printed beside the measured one
    if protocol:
        from .protocol.loader import find_protocol, load_protocol

        loaded = load_protocol(find_protocol(protocol))
        rig = loaded.protocol.rig
        required = {
            "analog_output": [rig.output.channel],
            "analog_input": [rig.input.angle_channel, rig.input.torque_channel],
        }
        source = loaded.rig_source
        rig_file = parse_rig_text(source.text, loaded.base_dir / source.shown, source.shown)
    result = check(required, timing=output_timing(rig_file))
    print(format_report(result))
    return EXIT_OK if result.ok else EXIT_HARDWARE_UNAVAILABLE


def export(path: Path, output: Path | None, *, only: KeySelection | None = None) -> int:
    """`--export`: cycles.csv, trials.csv and configurations.csv (default: `tables/` beside the archive);
    with `only`, the rows of those configuration keys alone (a key the archive lacks is refused)."""
    from .report.tidy import export_tables

    archive = _archive_of(path)
    out_dir = output if output is not None else archive.parent / "tables"
    files = export_tables(archive, out_dir, only=only)
    _result(f"wrote {', '.join(f.name for f in files)} to {out_dir}")
    return EXIT_OK


def compare(a: Path, b: Path, output: Path | None) -> int:
    """`--compare`: match configurations by settings, print the table and write the HTML page."""
    from .report.compare import compare_archives, render_comparison

    out = output if output is not None else Path("comparison.html")
    _html_output(out)
    archive_a, archive_b = _archive_of(a), _archive_of(b)
    result = compare_archives(archive_a, archive_b)
    print(result.table())
    render_comparison(result, out)
    _result(f"comparison: {out}")
    return EXIT_OK


def power_plan(
    protocol: str,
    *,
    session: Path | None,
    cv: float | None,
    effect_ratio: float | None,
    only: KeySelection | None = None,
) -> int:
    """`--plan PROTOCOL --power SESSION` (or `--power-cv CV`): the trials per configuration each declared
    expectation needs for 80 % power (power_plan.py)."""
    from .power_plan import Spread, check_session, plan_power
    from .protocol.plan import expand

    loaded = load_named(protocol)
    plan = expand(loaded, only=only)
    if not loaded.protocol.expectations:
        raise InvalidInput(f"{protocol} declares no expectations: there is no statement to plan trials for")
    if session is not None:
        from .report.load import load_report_data

        data = load_report_data(session)  # a missing, foreign or damaged archive: InvalidInput naming it
        warning = check_session(data, loaded, session)
        if warning:
            say(warning)
        spread = Spread(data=data, effect_ratio=effect_ratio)
    else:
        spread = Spread(cv=cv, effect_ratio=effect_ratio)
    print(plan_power(loaded, plan, spread).text())
    return EXIT_OK
