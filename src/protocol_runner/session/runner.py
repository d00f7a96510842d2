"""The runner: executes a plan's steps against a bench, one atomic unit per finished step.

For every step not yet journaled as complete: run it (steps/registry.py), write its unit atomically
(archive/units.py), then journal it. A resume skips journaled units whose files verify, redoes corrupt
or partial ones, and sets the rig up for the step it continues with (session/resume.py). SIGINT/SIGTERM
stop at the next safe point, park the joint, and exit 130 with the session resumable. At the end (and at
every stop) the units are consolidated into `archive.h5`, and the report is rendered.

The ideas it orders live apart: the analysis worker pool in `workers.py`, resuming in `resume.py`,
archive assembly in `assembly.py`, report triggering in `reporting.py`.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path

from ..archive.diskfull import DiskFull, disk_full_error, is_disk_full
from ..archive.units import unit_path
from ..errors import Interrupted, StoppedByCheck, UserError, file_system_refusal
from ..events import NULL_PUBLISHER, Publisher
from ..protocol.loader import LoadedProtocol
from ..protocol.plan import (
    CompareStep,
    Plan,
    Step,
)
from ..steps.context import Bench, StepOutcome, processing_settings
from ..steps.failures import run_step
from .assembly import ARCHIVE_NAME, ArchiveDraft, consolidate_session
from .early_figures import analysed_in_this_run, draw_ahead, final_configuration
from .journal import Journal
from .lock import session_lock
from .operator import Operator
from .progress import Progress
from .read_ahead import ReadAhead
from .reporting import render_report, start_warm_up
from .resume import prepare_resume
from .setup import SessionInfo
from .signals import StopFlag
from .unit_writer import UnitWriter, WritingStepContext, WrittenJournalView, written_in_this_run
from .workers import AnalysisPool, start_worker_server

UNIT_POLL_S = 0.005
"""How often a comparison waiting for a unit an analysis is writing looks for it."""


@dataclass(frozen=True)
class RunResult:
    status: str  # "complete", "incomplete", "aborted"
    archive: Path | None
    report: Path | None
    steps_run: int  # the plan's steps run (the report included): with steps_skipped, every step of the plan
    steps_skipped: int
    rechecks: int = 0  # the calibration checks a resume runs again before going on (not the plan's)


class Runner:
    def __init__(
        self,
        session_dir: Path,
        info: SessionInfo,
        loaded: LoadedProtocol,
        plan: Plan,
        bench: Bench,
        operator: Operator,
        *,
        resumed: bool = False,
        protocol_changed: bool = False,
        quiet: bool = False,
        stop: StopFlag | None = None,
        background: bool | None = None,
        publisher: Publisher = NULL_PUBLISHER,
    ) -> None:
        self.dir = session_dir
        self.info = info
        self.loaded = loaded
        self.plan = plan
        self.bench = bench
        self.operator = operator
        self.resumed = resumed
        self.protocol_changed = protocol_changed
        self.quiet = quiet
        self.units_dir = session_dir / "units"
        self.journal = Journal(session_dir / "journal.jsonl")
        self.stop = stop or StopFlag()
        self.steps_run = 0
        self.rechecks = 0
        self._planned = {step.id for step in plan.steps}
        self.background = background if background is not None else (os.cpu_count() or 1) >= 2
        self.ahead = ArchiveDraft(session_dir, self.journal)  # the archive merged while the analyses finish
        self.read_ahead = ReadAhead(plan, self.ahead)  # and the report's configurations read ahead
        self.pool = AnalysisPool(loaded, plan, self.units_dir, self.journal, self.read_ahead.offer)
        self.writer = UnitWriter(self.units_dir, self.journal)  # units written while the next step runs
        self.publisher = publisher  # the live monitor (--monitor): told of every step through `progress`

    # ------------------------------------------------------------------------------------------ run

    def run(self) -> RunResult:
        with session_lock(self.dir):
            return self._run()

    def _run(self) -> RunResult:
        self.started_ns = time.time_ns()  # units written from now on are this run's
        self.units_dir.mkdir(parents=True, exist_ok=True)
        for stray in self.units_dir.glob("*.partial"):
            stray.unlink()  # an unfinished unit from a crash: never complete, always redone
        self.stop.install()
        if self.background and any(s.background and s.id not in self.journal.units for s in self.plan.steps):
            start_worker_server()  # imports what the workers run, on the other core, meanwhile
        log = self.dir / "session.log"
        progress = Progress(
            self.plan, set(self.journal.units), log, quiet=self.quiet, publisher=self.publisher
        )
        ctx = WritingStepContext(
            loaded=self.loaded,
            plan=self.plan,
            bench=self.bench,
            operator=self.operator,
            units_dir=self.units_dir,
            journal=WrittenJournalView(self.journal, self.writer),
            stop_requested=self.stop,
            processing=processing_settings(self.loaded),
            monitor=self.publisher,
            writer=self.writer,
        )
        skipped = 0
        try:
            if self.resumed:
                prepare_resume(self, ctx, progress)  # session/resume.py
            else:
                self.journal.event("started", f"{self.info.mode}, seed {self.info.seed}")
                self.journal.event("referenced_files", json.dumps(self.info.files_sha256, sort_keys=True))
            for step in self.plan.steps:
                self.writer.collect()  # journal the units written meanwhile (and surface a write error)
                self.pool.collect(self._finished(progress), wait=False)
                if step.id in self.journal.units:
                    skipped += 1
                    continue
                if self.stop():
                    raise Interrupted(f"stopped before {step.id} ({self.stop.signal_name})")
                if step.id in self.pool.submitted:
                    continue
                if self.background and step.background:
                    # handed to a worker once the configuration's units are on disk
                    self.pool.submit(step, ready=self.writer.ticket())
                    continue
                after: list[str] = []  # units the step read that are not journaled yet
                if step.kind in ("compare", "report"):
                    # the report's imports and caches, while the last analyses finish (the workers draw)
                    start_warm_up(drawing=not self.pool.running)
                    # A comparison runs as soon as the processing units it reads are on disk, while the
                    # last fits may still run, and the comparisons one after the other without waiting for
                    # each other's units: the unit writer saves each while the next runs, and journals it
                    # once the units it read are journaled. The report step waits for all of them.
                    if isinstance(step, CompareStep):
                        after = self._await_units(list(step.inputs()), progress) if self.pool.busy else []
                    else:
                        self.writer.flush()  # what the analyses read is on disk
                        self._await_analyses(progress)
                        self.writer.collect()  # the comparisons held for them
                    if self.stop():  # a Ctrl-C while the last analyses ran: stop here, as announced
                        raise Interrupted(f"stopped before {step.id} ({self.stop.signal_name})")
                if step.kind == "report":
                    return self._finish(progress, skipped)
                progress.step_started(step)
                if self.bench.paced and step.robot_time_s > 0:
                    # On the robot a step lasts a minute: journal the last one's unit before it starts,
                    # so that a crash or power cut during it cannot make a resume record it again.
                    self.writer.flush()
                outcome = run_step(step, ctx)
                self.record(step.id, outcome, after=after)
                progress.step_finished(step, outcome.summary, after=after)
            self.writer.flush()
            self._await_analyses(progress)
            return self._finish(progress, skipped)
        except Interrupted as exc:
            self._stopped("interrupted", exc.message, progress)
            raise Interrupted(
                f"{exc.message}. The session is resumable: run-protocol --resume {self.dir}"
            ) from None
        except KeyboardInterrupt:
            self.pool.kill()
            self.writer.abandon()
            with contextlib.suppress(Exception):
                self.journal.event("interrupted", "stopped at once (second Ctrl-C)")
            raise Interrupted(
                f"stopped at once; every finished step is kept. Resume with: run-protocol --resume {self.dir}"
            ) from None
        except StoppedByCheck as exc:
            self._stopped("aborted", exc.message, progress)
            raise
        except DiskFull as exc:
            raise self._disk_full(exc) from None
        except UserError as exc:
            self._stopped("stopped", exc.message, progress)
            if not getattr(exc, "resumable", True):
                raise  # its message says what to do (steps/failures.py)
            raise type(exc)(
                f"{exc.message}\nThe session is resumable: run-protocol --resume {self.dir}"
            ) from None
        except Exception as exc:  # a bug: keep what was finished, record it, and let the traceback show
            if is_disk_full(exc):  # not a bug: the journal or the report could not be written either
                raise self._disk_full(exc) from None
            refusal = file_system_refusal(exc)
            if refusal is not None:  # the file system said no (a directory where a unit belongs, ...)
                self._stopped("stopped", refusal, progress)
                raise
            progress.logger.exception("internal error")
            self._stopped("stopped", f"internal error: {exc!r} (traceback in session.log)", progress)
            raise
        finally:
            with contextlib.suppress(Exception):  # flushed on every path above; an error is already raised
                self.writer.close()
            try:
                self.pool.shutdown(progress.step_finished)
            except KeyboardInterrupt:  # Ctrl-C while waiting for the analyses: stop them now
                self.pool.kill()
            self.stop.uninstall()
            progress.close()
            with contextlib.suppress(Exception):
                self.bench.close()

    def _finished(self, progress: Progress) -> Callable[[Step, str], None]:
        def finished(step: Step, summary: str) -> None:
            self.steps_run += 1
            progress.step_finished(step, summary, background=True)
            progress.release(self.journal.units)  # a comparison's line after the processing it read

        return finished

    def _await_analyses(self, progress: Progress) -> None:
        """Wait for every analysis to be journaled, meanwhile merging the units already journaled into the
        archive's draft (`assembly.ArchiveDraft`): consolidation at the end then adds only the last ones."""
        finished = self._finished(progress)
        self.pool.collect(finished, wait=False)
        self.ahead.update()
        self.read_ahead.update()
        while self.pool.busy:
            self.pool.wait_any()
            self.pool.collect(finished, wait=False)
            if self.pool.busy:  # the last one's units are merged at the end, not here
                self.ahead.update()
                self.read_ahead.update()
        self.read_ahead.update(draft=False)  # what the last analyses' worker read (nothing to read here)

    def _await_units(self, step_ids: list[str], progress: Progress) -> list[str]:
        """Wait until the units `step_ids` are on disk: journaled, or written in this run by an analysis whose
        task has not ended (a unit is complete once renamed into place; it is journaled when its task ends,
        `written_in_this_run`). Returns those not journaled yet."""
        finished = self._finished(progress)

        def missing() -> list[str]:
            self.pool.collect(finished, wait=False)
            return [
                step_id
                for step_id in step_ids
                if step_id not in self.journal.units
                and not written_in_this_run(unit_path(self.units_dir, step_id), self.started_ns)
            ]

        merged = len(self.journal.units)
        while self.pool.busy and missing():
            if len(self.journal.units) != merged:  # meanwhile, the draft as `_await_analyses` keeps it
                merged = len(self.journal.units)
                self.ahead.update()
                self.read_ahead.update()
            if self.pool.queued:
                self.writer.flush()  # wait_any hands them out: what they read must be on disk
            self.pool.wait_any(timeout_s=UNIT_POLL_S)
        return [step_id for step_id in step_ids if step_id not in self.journal.units]

    def record(self, step_id: str, outcome: StepOutcome, *, after: Sequence[str] = ()) -> None:
        """Hand the step's unit to the writer (journaled once it is on disk, and once the units `after` are
        journaled); a step that stops the session has its unit written and journaled before the stop is
        raised."""
        if outcome.fill is not None:
            self.writer.submit(step_id, outcome.fill, final=outcome.stop is None, after=after)
        if step_id in self._planned:
            self.steps_run += 1
        else:
            self.rechecks += 1
        if outcome.stop is not None:
            self.writer.flush()
            raise outcome.stop

    # ------------------------------------------------------------------------------------ finishing

    def _stopped(self, kind: str, message: str, progress: Progress) -> None:
        """Record the stop, park, consolidate. A second Ctrl-C meanwhile cuts this short (--resume redoes it)."""
        status = "aborted" if kind == "aborted" else "incomplete"
        actions = (
            lambda: self._flush_units(progress),  # journal every unit written so far
            lambda: self.pool.shutdown(progress.step_finished),  # keep the analyses that finish meanwhile
            self.writer.collect,  # the comparisons held for those analyses
            lambda: self.journal.event(kind, message),
            lambda: self.bench.rig.park(where="park on stop"),
            lambda: self.consolidate(status),
            lambda: progress.release(self.journal.units, every=True),
            lambda: progress.info(f"session {kind}: {message}"),
        )
        for action in actions:
            try:
                action()
            except KeyboardInterrupt:
                self.pool.kill()
                self.writer.abandon()
                with contextlib.suppress(Exception):
                    self.journal.event("interrupted", "stopped at once (second Ctrl-C)")
                return
            except Exception:  # a stop must get through every action it can
                continue

    def _flush_units(self, progress: Progress) -> None:
        """On a stop: wait for the units being written and journal them; a write that failed meanwhile is
        recorded (its step is redone on resume)."""
        try:
            self.writer.flush()
        except Exception as exc:
            self.journal.event("unit_not_written", f"{exc}")
            progress.info(f"a unit could not be written ({exc}); its step is redone on resume")

    def _disk_full(self, exc: Exception) -> DiskFull:
        """Park, journal the stop if there is room for it, and the error to raise (archive/diskfull.py)."""
        with contextlib.suppress(Exception):
            self.writer.flush()  # the units written before the full disk are kept
        with contextlib.suppress(Exception):
            self.journal.event("interrupted", "disk full")
        with contextlib.suppress(Exception):
            self.bench.rig.park(where="park after disk full")
        return exc if isinstance(exc, DiskFull) else disk_full_error(exc, self.dir)

    def _finish(self, progress: Progress, skipped: int) -> RunResult:
        clock = getattr(getattr(self.bench, "sim", None), "clock", None)
        robot = f"; {clock.now_s():.1f} s of robot time simulated" if clock is not None else ""
        self.writer.flush()
        if self.writer.held:  # every analysis is journaled by now: a unit still waiting would be lost
            raise RuntimeError(
                f"units {', '.join(self.writer.held)} wait for units that were never journaled"
            )
        if self.plan.steps and self.plan.steps[-1].kind == "report":
            self.steps_run += 1  # written below
        self.journal.event("finished", f"{self.steps_run} steps run, {skipped} skipped{robot}")
        progress.release(self.journal.units, every=True)
        final = self._draw_final_configuration()  # on a worker, while this process consolidates
        archive = self.consolidate("complete")
        call = self.pool.call if self.pool.running else None  # the workers draw the figures left
        ahead = (final,) if final is not None else ()
        report = render_report(self.dir, archive, self.read_ahead.known(), call, ahead)
        if self.plan.steps and self.plan.steps[-1].kind == "report":
            progress.step_finished(self.plan.steps[-1], "archive and report written")
        progress.info(f"archive: {archive}")
        if report is not None:
            progress.info(f"report:  {report}")
        return RunResult("complete", archive, report, self.steps_run, skipped, self.rechecks)

    def _draw_final_configuration(self) -> Future[object] | None:
        """The figures of the plan's last configuration, drawn ahead on a worker (idle now) when its analyses
        ended in this run: the other configurations' are drawn by the worker that ends their analyses, but
        this one's units are awaited before consolidation, which then need not wait for its drawing."""
        key = final_configuration(self.plan)
        if (
            key is None
            or not self.pool.running
            or not analysed_in_this_run(self.plan, key, self.pool.submitted)
        ):
            return None
        return self.pool.call(draw_ahead, self.plan, self.units_dir, key, self.dir / ARCHIVE_NAME)

    def consolidate(self, status: str) -> Path:
        return consolidate_session(
            self.dir, self.info, self.loaded, self.plan, self.journal, status, self.ahead
        )
