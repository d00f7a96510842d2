"""The runner: executes a plan's steps against a bench, one atomic unit per finished step.

For every step not yet journaled as complete: run it (steps/registry.py), write its unit atomically
(archive/units.py), then journal it. A resume skips journaled units whose files verify, redoes corrupt
or partial ones, and sets the rig up for the step it continues with (session/resume.py). SIGINT/SIGTERM
stop at the next safe point, park the joint, and exit 130 with the session resumable. At the end (and at
every stop) the units are consolidated into `archive.h5`, and the report is rendered.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import signal
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from dataclasses import dataclass
from pathlib import Path

from ..archive.consolidate import ArchiveMeta, consolidate
from ..archive.diskfull import DiskFull, disk_full_error, is_disk_full, resume_hint
from ..archive.units import UnitRecord, checked_unit_files, write_unit
from ..errors import Interrupted, StoppedByCheck, UserError
from ..monitor.publisher import NULL_PUBLISHER, Publisher
from ..protocol.loader import LoadedProtocol
from ..protocol.plan import (
    Plan,
    ProcessStep,
    Step,
    TrialStep,
    configuration_name,
)
from ..steps.context import Bench, StepContext, StepOutcome, processing_settings
from ..steps.failures import run_step
from .journal import Journal, utc_now
from .lock import session_lock
from .operator import Operator
from .progress import Progress
from .resume import prepare_resume
from .setup import SessionInfo
from .signals import StopFlag, sigint_blocked

ARCHIVE_NAME = "archive.h5"
REPORT_NAME = "report.html"

# Steps that only read finished units (never the rig): on a machine with two cores or more they run in a
# worker process while the main process goes on with the next set's trials. They are journaled, like any
# step, only once their unit is on disk; a stop waits for the one in progress and redoes the rest.
BACKGROUND_KINDS = frozenset({"process", "fit"})


def _worker_init() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process decides when to stop
    # Linux: die with the session process, so a killed session leaves no worker behind writing units
    with contextlib.suppress(Exception):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
        if os.getppid() == 1:  # the parent died before prctl took effect
            os._exit(1)


def run_analysis_steps(
    loaded: LoadedProtocol, plan: Plan, units_dir: Path, step_ids: tuple[str, ...]
) -> list[tuple[UnitRecord | None, str]]:
    """Run analysis steps (in order) from the archived units and write their units (in a worker process)."""
    ctx = StepContext(
        loaded=loaded,
        plan=plan,
        bench=None,  # type: ignore[arg-type]  # analysis steps never touch the rig
        operator=None,  # type: ignore[arg-type]
        units_dir=units_dir,
        journal=None,  # type: ignore[arg-type]
        stop_requested=lambda: False,
        processing=processing_settings(loaded),
    )
    done: list[tuple[UnitRecord | None, str]] = []
    for step_id in step_ids:
        step = plan.step(step_id)
        outcome = run_step(step, ctx)
        record = write_unit(units_dir, step.id, outcome.fill) if outcome.fill is not None else None
        done.append((record, outcome.summary))
    return done


@dataclass(frozen=True)
class RunResult:
    status: str  # "complete", "incomplete", "aborted"
    archive: Path | None
    report: Path | None
    steps_run: int
    steps_skipped: int


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
        self.background = background if background is not None else (os.cpu_count() or 1) >= 2
        self._pool: ProcessPoolExecutor | None = None
        self._pending: list[tuple[tuple[Step, ...], Future[list[tuple[UnitRecord | None, str]]]]] = []
        self._submitted: set[str] = set()
        self.publisher = publisher  # the live monitor (--monitor): told of every step through `progress`

    # ------------------------------------------------------------------------------------------ run

    def run(self) -> RunResult:
        with session_lock(self.dir):
            return self._run()

    def _run(self) -> RunResult:
        self.units_dir.mkdir(parents=True, exist_ok=True)
        for stray in self.units_dir.glob("*.partial"):
            stray.unlink()  # an unfinished unit from a crash: never complete, always redone
        self.stop.install()
        log = self.dir / "session.log"
        progress = Progress(
            self.plan, set(self.journal.units), log, quiet=self.quiet, publisher=self.publisher
        )
        ctx = StepContext(
            loaded=self.loaded,
            plan=self.plan,
            bench=self.bench,
            operator=self.operator,
            units_dir=self.units_dir,
            journal=self.journal,
            stop_requested=self.stop,
            processing=processing_settings(self.loaded),
            monitor=self.publisher,
        )
        skipped = 0
        try:
            if self.resumed:
                prepare_resume(self, ctx, progress)  # session/resume.py
            else:
                self.journal.event("started", f"{self.info.mode}, seed {self.info.seed}")
                self.journal.event("referenced_files", json.dumps(self.info.files_sha256, sort_keys=True))
            for step in self.plan.steps:
                self._collect(progress, wait=False)
                if step.id in self.journal.units:
                    skipped += 1
                    continue
                if self.stop():
                    raise Interrupted(f"stopped before {step.id} ({self.stop.signal_name})")
                if step.id in self._submitted:
                    continue
                if self.background and step.kind in BACKGROUND_KINDS:
                    self._submit(step)
                    continue
                if step.kind in ("compare", "report"):
                    self._collect(progress, wait=True)  # these read the analyses' units
                if step.kind == "report":
                    return self._finish(progress, skipped)
                progress.step_started(step)
                outcome = run_step(step, ctx)
                self._record(step.id, outcome)
                progress.step_finished(step, outcome.summary)
            self._collect(progress, wait=True)
            return self._finish(progress, skipped)
        except Interrupted as exc:
            self._stopped("interrupted", exc.message, progress)
            raise Interrupted(
                f"{exc.message}. The session is resumable: run-protocol --resume {self.dir}"
            ) from None
        except KeyboardInterrupt:
            self._kill_pool()
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
            progress.logger.exception("internal error")
            self._stopped("stopped", f"internal error: {exc!r} (traceback in session.log)", progress)
            raise
        finally:
            try:
                self._shutdown_pool(progress)
            except KeyboardInterrupt:  # Ctrl-C while waiting for the analyses: stop them now
                self._kill_pool()
            self.stop.uninstall()
            progress.close()
            with contextlib.suppress(Exception):
                self.bench.close()

    def _submit(self, step: Step) -> None:
        """Queue a configuration's processing together with its fit (one task: the fit needs its unit)."""
        if self._pool is None:
            workers = min(2, os.cpu_count() or 1)
            self._pool = ProcessPoolExecutor(
                max_workers=workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_worker_init,
            )
        chain = [step]
        if isinstance(step, ProcessStep):
            fit = f"fit:k{step.configuration:02d}"
            if fit in self.plan._index and fit not in self.journal.units:
                chain.append(self.plan.step(fit))
        self._submitted.update(s.id for s in chain)
        with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
            future = self._pool.submit(
                run_analysis_steps, self.loaded, self.plan, self.units_dir, tuple(s.id for s in chain)
            )
        self._pending.append((tuple(chain), future))

    def _collect(self, progress: Progress, *, wait: bool) -> None:
        """Journal the background steps that finished (all of them when `wait`)."""
        still: list[tuple[tuple[Step, ...], Future[list[tuple[UnitRecord | None, str]]]]] = []
        for chain, future in self._pending:
            if not (wait or future.done()):
                still.append((chain, future))
                continue
            results = future.result()  # a worker's error is raised here, in the main process
            for step, (record, summary) in zip(chain, results, strict=True):
                if record is not None:
                    self.journal.unit_done(record)
                self.steps_run += 1
                progress.step_finished(step, summary)
        self._pending = still

    def _shutdown_pool(self, progress: Progress) -> None:
        """On any exit: keep the background steps that completed, drop the queued ones (redone on resume)."""
        if self._pool is None:
            return
        for _, future in self._pending:
            future.cancel()
        # wait for the running ones here, not inside the pool's shutdown: a second Ctrl-C meanwhile must not
        # interrupt the pool's own bookkeeping (see _kill_pool)
        futures_wait([future for _, future in self._pending])
        self._pool.shutdown(wait=True, cancel_futures=True)
        for chain, future in self._pending:
            if future.cancelled() or future.exception() is not None:
                continue
            with contextlib.suppress(Exception):
                for step, (record, summary) in zip(chain, future.result(), strict=True):
                    if record is not None:
                        self.journal.unit_done(record)
                    progress.step_finished(step, summary)
        self._pending.clear()
        self._pool = None

    def _kill_pool(self) -> None:
        """Stop at once: end the analysis workers (units are atomic: an unfinished one is redone on resume)."""
        if self._pool is None:
            return
        for proc in list(getattr(self._pool, "_processes", {}).values()):
            with contextlib.suppress(Exception):
                proc.kill()
        with contextlib.suppress(Exception):  # quick with the workers gone; its thread must end before exit
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()
        self._pool = None

    def _record(self, step_id: str, outcome: StepOutcome) -> None:
        if outcome.fill is not None:
            record = write_unit(self.units_dir, step_id, outcome.fill)
            self.journal.unit_done(record, final=outcome.stop is None)
        self.steps_run += 1
        if outcome.stop is not None:
            raise outcome.stop

    # ------------------------------------------------------------------------------------ finishing

    def _stopped(self, kind: str, message: str, progress: Progress) -> None:
        """Record the stop, park, consolidate. A second Ctrl-C meanwhile cuts this short (--resume redoes it)."""
        status = "aborted" if kind == "aborted" else "incomplete"
        actions = (
            lambda: self._shutdown_pool(progress),  # keep the analyses that finish meanwhile
            lambda: self.journal.event(kind, message),
            lambda: self.bench.rig.park(where="park on stop"),
            lambda: self.consolidate(status),
            lambda: progress.info(f"session {kind}: {message}"),
        )
        for action in actions:
            try:
                action()
            except KeyboardInterrupt:
                self._kill_pool()
                with contextlib.suppress(Exception):
                    self.journal.event("interrupted", "stopped at once (second Ctrl-C)")
                return
            except Exception:  # a stop must get through every action it can
                continue

    def _disk_full(self, exc: Exception) -> DiskFull:
        """Park, journal the stop if there is room for it, and the error to raise (archive/diskfull.py)."""
        with contextlib.suppress(Exception):
            self.journal.event("interrupted", "disk full")
        with contextlib.suppress(Exception):
            self.bench.rig.park(where="park after disk full")
        return exc if isinstance(exc, DiskFull) else disk_full_error(exc, self.dir)

    def _finish(self, progress: Progress, skipped: int) -> RunResult:
        clock = getattr(getattr(self.bench, "sim", None), "clock", None)
        robot = f"; {clock.now_s():.1f} s of robot time simulated" if clock is not None else ""
        self.journal.event("finished", f"{self.steps_run} steps run, {skipped} skipped{robot}")
        archive = self.consolidate("complete")
        report = self.render_report(archive)
        if self.plan.steps and self.plan.steps[-1].kind == "report":
            progress.step_finished(self.plan.steps[-1], "archive and report written")
        progress.info(f"archive: {archive}")
        if report is not None:
            progress.info(f"report:  {report}")
        return RunResult("complete", archive, report, self.steps_run, skipped)

    def configuration_attrs(self) -> dict[str, dict[str, object]]:
        out: dict[str, dict[str, object]] = {}
        done = self.journal.units
        for step in self.plan.steps:
            if not isinstance(step, TrialStep):
                continue
            name = configuration_name(step.configuration)
            entry = out.setdefault(name, {"key": step.configuration, "n_trials": 0, "_any": False})
            if step.brace == "on":
                entry["n_trials"] = int(entry["n_trials"]) + 1  # type: ignore[call-overload]
            entry["_any"] = bool(entry["_any"]) or step.id in done
        for entry in out.values():
            key = int(entry["key"])  # type: ignore[call-overload]
            fitted = f"fit:k{key:02d}" in done or (
                f"process:k{key:02d}" in done and f"fit:k{key:02d}" not in self.plan._index
            )
            entry["status"] = "complete" if fitted else ("partial" if entry.pop("_any") else "not run")
            entry.pop("_any", None)
        return out

    def consolidate(self, status: str) -> Path:
        records = list(self.journal.units.values()) + list(self.journal.failed.values())
        files = checked_unit_files(self.units_dir, records)
        meta = ArchiveMeta(
            protocol_name=self.info.protocol_name,
            protocol_sha256=self.loaded.sha256,
            protocol_text=self.loaded.text,
            protocol_filename=self.loaded.path.name,
            plan_json=json.dumps(self.plan.to_json()),
            mode=self.info.mode,
            seed=self.info.seed,
            created_utc=self.info.created_utc,
            finished_utc=utc_now(),
            status=status,
            joint=self.loaded.protocol.rig.joint.name,
            only=self.info.only,
            events=tuple(json.dumps(e.to_json()) for e in self.journal.events),
            configuration_attrs=self.configuration_attrs(),
            reference=self.reference_dataset(),
        )
        return consolidate(self.dir / ARCHIVE_NAME, files, meta)

    def reference_dataset(self) -> tuple[str, str, object, object] | None:
        """The protocol's EMU reference dataset (§5.6), copied into the archive so the report needs nothing else."""
        rel = self.loaded.protocol.report.reference_dataset
        if rel is None:
            return None
        from ..report.load import load_reference_dataset

        ref = load_reference_dataset(self.loaded.base_dir / rel)
        return (Path(rel).stem, rel, ref.angle_deg, ref.torque_nm)

    def render_report(self, archive: Path) -> Path | None:
        try:
            from ..report.render import generate_report
        except ImportError:  # the report module is optional until it lands
            return None
        try:
            from ..archive.verdicts import record_verdicts

            record_verdicts(archive)  # /expectations: the declared expectations and their verdicts
            return generate_report(archive, self.dir / REPORT_NAME)
        except OSError as exc:
            if not is_disk_full(exc):
                raise
            where = f"{self.dir / REPORT_NAME} (the archive is complete)"
            raise DiskFull(f"disk full while writing {where}. {resume_hint(self.dir)}") from None
