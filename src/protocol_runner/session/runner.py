"""The runner: executes a plan's steps against a bench, one atomic unit per finished step.

One loop over the plan's steps: skip a step the journal lists as complete; run the step; write its unit
(archive/units.py: written, fsynced, renamed into place); journal it. Every unit is on disk and journaled
before the next step moves the joint, so a crash or a kill loses at most the step under way. SIGINT/SIGTERM
stop at the next safe point, park the joint, and exit 130 with the session resumable (`resume.py`). At the
end (and at every stop) the units are consolidated into `archive.h5`, and the report is rendered.

With two cores or more, the analysis steps (which only read finished units) run in a worker process
(`workers.py`) while the loop goes on with the next trials; the loop journals each once its unit is on
disk, and waits for all of them before a comparison or the report reads them.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Mapping
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass
from pathlib import Path

from ..analysis.reference import load_reference_dataset
from ..archive.consolidate import ArchiveMeta, consolidate
from ..archive.diskfull import DiskFull, disk_full_error, is_disk_full
from ..archive.paths import configuration_name
from ..archive.units import checked_unit_files, write_unit
from ..errors import Interrupted, StoppedByCheck, UserError, file_system_refusal
from ..events import NULL_PUBLISHER, Publisher
from ..protocol.loaded import LoadedProtocol
from ..protocol.plan_steps import Plan, Step, TrialStep
from ..protocol.processing import processing_settings
from ..protocol.step_ids import step_id as make_step_id
from ..protocol.wording import counted
from ..steps.context import Bench, StepContext, StepOutcome
from ..steps.failures import run_step
from ..steps.operator import Operator
from .journal import Journal, utc_now
from .lock import refuse_session_links, session_lock
from .progress import Progress
from .reporting import render_report
from .resume import prepare_resume
from .setup import SessionInfo
from .signals import StopFlag
from .workers import AnalysisPool


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
        refuse_session_links(session_dir)  # lock, journal, log, units: never written through a link
        self.journal = Journal(session_dir / "journal.jsonl")
        self.stop = StopFlag()
        self.steps_run = 0
        self.rechecks = 0
        self._planned = {step.id for step in plan.steps}
        self.background = (os.cpu_count() or 1) >= 2
        self.pool = AnalysisPool(loaded, plan, self.units_dir, self.journal)
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

        def analysed(step: Step, summary: str) -> None:  # an analysis the workers ran is journaled
            self.steps_run += 1
            progress.step_finished(step, summary)

        try:
            if self.resumed:
                prepare_resume(self, ctx, progress)  # session/resume.py
            else:
                self.journal.event("started", f"{self.info.mode}, seed {self.info.seed}")
                self.journal.event("referenced_files", json.dumps(self.info.files_sha256, sort_keys=True))
            for step in self.plan.steps:
                self.pool.collect(analysed)  # journal the analyses finished meanwhile
                if step.id in self.journal.units:
                    skipped += 1
                    continue
                if self.stop():
                    raise Interrupted(f"stopped before {step.id} ({self.stop.signal_name})")
                if step.id in self.pool.submitted:
                    continue  # a fit, run by the worker that runs its processing
                if self.background and step.background:
                    self.pool.submit(step)  # the units it reads are journaled: on disk
                    continue
                if step.kind in ("compare", "report"):
                    self.pool.collect(analysed, wait=True)  # what they read
                    if self.stop():  # a Ctrl-C while the last analyses ran: stop here, as announced
                        raise Interrupted(f"stopped before {step.id} ({self.stop.signal_name})")
                if step.kind == "report":
                    return self._finish(progress, skipped)
                progress.step_started(step)
                outcome = run_step(step, ctx)
                self.record(step.id, outcome)
                progress.step_finished(step, outcome.summary)
            self.pool.collect(analysed, wait=True)
            return self._finish(progress, skipped)
        except Interrupted as exc:
            message = exc.message
            if self.stop() and self.stop.signal_name not in message:  # stopped inside a motion: say by what
                message = f"{message} ({self.stop.signal_name})"
            self._stopped("interrupted", message, progress)
            raise Interrupted(
                f"{message}. The session is resumable: run-protocol --resume {self.dir}"
            ) from None
        except KeyboardInterrupt:
            self._stopped_at_once()
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
            if isinstance(exc, BrokenProcessPool) and self.stop():  # a worker ended during a stop
                self._stopped("interrupted", f"{self.stop.signal_name}; an analysis worker ended", progress)
                raise Interrupted(
                    f"stopped ({self.stop.signal_name}). The session is resumable: run-protocol --resume {self.dir}"
                ) from None
            refusal = file_system_refusal(exc)
            if refusal is not None:  # the file system said no (a directory where a unit belongs, ...)
                self._stopped("stopped", refusal, progress)
                raise
            progress.logger.exception("internal error")
            self._stopped("stopped", f"internal error: {exc!r} (traceback in session.log)", progress)
            raise
        finally:
            try:
                self.pool.shutdown(progress.step_finished)
            except KeyboardInterrupt:  # Ctrl-C while waiting for the analyses: stop them now
                self.pool.kill()
            self.stop.uninstall()
            progress.close()
            with contextlib.suppress(Exception):
                self.bench.close()

    def record(self, step_id: str, outcome: StepOutcome) -> None:
        """Write the step's unit and journal it; a step that stops the session has its unit written and
        journaled before the stop is raised."""
        if outcome.fill is not None:
            self.journal.unit_done(
                write_unit(self.units_dir, step_id, outcome.fill), final=outcome.stop is None
            )
        if step_id in self._planned:
            self.steps_run += 1
        else:
            self.rechecks += 1
        if outcome.stop is not None:
            raise outcome.stop

    # ------------------------------------------------------------------------------------ finishing

    def _stopped(self, kind: str, message: str, progress: Progress) -> None:
        """Record the stop, park, consolidate. A second Ctrl-C meanwhile cuts this short (--resume redoes it)."""
        status = "aborted" if kind == "aborted" else "incomplete"
        actions = (
            lambda: self.pool.shutdown(progress.step_finished),  # keep the analyses that finish meanwhile
            lambda: self.journal.event(kind, message),
            lambda: self.bench.rig.park(where="park on stop"),
            lambda: self.consolidate(status),
            lambda: progress.info(f"session {kind}: {message}"),
        )
        for action in actions:
            try:
                action()
            except KeyboardInterrupt:
                self._stopped_at_once()
                return
            except Exception:  # a stop must get through every action it can
                continue

    def _stopped_at_once(self) -> None:  # a second Ctrl-C
        self.pool.kill()
        with contextlib.suppress(Exception):
            self.journal.event("interrupted", "stopped at once (second Ctrl-C)")

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
        if self.plan.steps and self.plan.steps[-1].kind == "report":
            self.steps_run += 1  # written below
        self.journal.event("finished", f"{counted(self.steps_run, 'step')} run, {skipped} skipped{robot}")
        archive = self.consolidate("complete")
        self.pool.shutdown(progress.step_finished)  # every analysis is journaled: the workers are done
        report = render_report(self.dir, archive)
        if self.plan.steps and self.plan.steps[-1].kind == "report":
            progress.step_finished(self.plan.steps[-1], "archive and report written")
        progress.info(f"archive: {archive}")
        if report is not None:
            progress.info(f"report:  {report}")
        return RunResult("complete", archive, report, self.steps_run, skipped, self.rechecks)

    def consolidate(self, status: str) -> Path:
        """The session's finished (and failed-but-kept) units, checked, into `archive.h5` with the
        session's metadata."""
        records = list(self.journal.units.values()) + list(self.journal.failed.values())
        files = checked_unit_files(self.units_dir, records)
        root = {
            "protocol_name": self.info.protocol_name,
            "protocol_sha256": self.loaded.sha256,
            "rig_sha256": self.loaded.rig_source.sha256,
            "mode": self.info.mode,
            "seed": int(self.info.seed),
            "created_utc": self.info.created_utc,
            "finished_utc": utc_now(),
            "status": status,
            "joint": ",".join(self.loaded.protocol.driven_joints),
        }
        meta = ArchiveMeta(
            root=root,
            protocol_text=self.loaded.text,
            protocol_filename=self.loaded.path.name,
            rig_text=self.loaded.rig_source.text,
            rig_filename=self.loaded.rig_source.shown,
            plan_json=json.dumps(self.plan.to_json()),
            only=self.info.only,
            events=tuple(json.dumps(asdict(e)) for e in self.journal.events),
            configuration_attrs=configuration_attrs(self.plan, self.journal.units),
            reference=reference_dataset(self.loaded),
        )
        return consolidate(self.dir / "archive.h5", files, meta)


def configuration_attrs(plan: Plan, done: Mapping[str, object]) -> dict[str, dict[str, object]]:
    """Per configuration group: its key, number of trials and status (complete, partial, not run)."""
    out: dict[str, dict[str, object]] = {}
    for step in plan.steps:
        if not isinstance(step, TrialStep):
            continue
        name = configuration_name(step.configuration)
        entry = out.setdefault(name, {"key": step.configuration, "n_trials": 0, "_any": False})
        if step.brace == "on":
            entry["n_trials"] = int(entry["n_trials"]) + 1  # type: ignore[call-overload]
        entry["_any"] = bool(entry["_any"]) or step.id in done
    for entry in out.values():
        key = int(entry["key"])  # type: ignore[call-overload]
        fit, process = make_step_id("fit", key=key), make_step_id("process", key=key)
        fitted = fit in done or (process in done and fit not in plan)
        entry["status"] = "complete" if fitted else ("partial" if entry.pop("_any") else "not run")
        entry.pop("_any", None)
    return out


def reference_dataset(loaded: LoadedProtocol) -> tuple[str, str, object, object] | None:
    """The protocol's EMU reference dataset (§5.6), copied into the archive so the report needs nothing else."""
    rel = loaded.protocol.report.reference_dataset
    if rel is None:
        return None
    ref = load_reference_dataset(loaded.base_dir / rel)
    return (Path(rel).stem, rel, ref.angle_deg, ref.torque_nm)
