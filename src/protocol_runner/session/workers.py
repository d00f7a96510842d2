"""The analysis worker pool: processing and fit steps run in a worker process beside the trials.

Steps that only read finished units (never the rig) run, on a machine with two cores or more, in a
worker process while the main process goes on with the next set's trials. They are journaled, like any
step, only once their unit is on disk; a stop waits for the one in progress and redoes the rest.

A step submitted with a `ready` test (the unit writer's ticket, `session/unit_writer.py`) is handed to a
worker only once the test passes — once the units it reads are on disk — at a later `submit` or `collect`;
the main process does not wait for the writer meanwhile.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import TypeVar

from ..archive.units import UnitRecord, write_unit
from ..protocol.loader import LoadedProtocol
from ..protocol.plan import Plan, ProcessStep, Step
from ..protocol.processing import processing_settings
from ..protocol.step_ids import step_id as make_step_id
from ..steps.context import StepContext
from ..steps.failures import run_step
from .assembly import ARCHIVE_NAME
from .early_figures import UnitsRead, draw_ahead, key_to_draw_ahead
from .journal import Journal
from .signals import sigint_blocked
from .worker_start import start_worker_server, worker_context
from .worker_start import worker_init as worker_init

BACKGROUND_KINDS = frozenset({"process", "fit"})

Results = list[tuple[UnitRecord | None, str]]
Task = tuple[Results, UnitsRead | None]  # a task's units and summaries, and its configuration as read ahead
T = TypeVar("T")


# in a worker: the pool's protocol and plan (`_start_worker`)
_SESSION: list[tuple[LoadedProtocol, Plan]] = []


def _start_worker(loaded: LoadedProtocol, plan: Plan) -> None:
    """A worker's start (`worker_init`), keeping the session's protocol and plan for every task it runs: they
    reach each worker once, with the worker, instead of with each of its tasks (about 0.16 MB pickled and
    3 ms of CPU a task for the knee)."""
    worker_init()
    _SESSION[:] = [(loaded, plan)]


def _run_task(units_dir: Path, step_ids: tuple[str, ...]) -> Task:
    """`run_analysis_steps` with the protocol and plan the worker started with."""
    loaded, plan = _SESSION[0]
    return run_analysis_steps(loaded, plan, units_dir, step_ids)


def run_analysis_steps(
    loaded: LoadedProtocol, plan: Plan, units_dir: Path, step_ids: tuple[str, ...]
) -> Task:
    """Run analysis steps (in order) from the archived units and write their units (in a worker process);
    with them, the configuration whose analyses they end as read for its figures (`draw_ahead`), if any."""
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
    done: Results = []
    for step_id in step_ids:
        step = plan.step(step_id)
        outcome = run_step(step, ctx)
        record = write_unit(units_dir, step.id, outcome.fill) if outcome.fill is not None else None
        done.append((record, outcome.summary))
    key = key_to_draw_ahead(plan, step_ids)
    if key is None:
        return done, None
    # the configuration's analyses are written: its report figures now, not at the end
    return done, draw_ahead(plan, units_dir, key, units_dir.parent / ARCHIVE_NAME)


class AnalysisPool:
    """Background analysis steps: submitted in plan order, journaled in the main process when done."""

    def __init__(
        self,
        loaded: LoadedProtocol,
        plan: Plan,
        units_dir: Path,
        journal: Journal,
        read: Callable[[UnitsRead], None] | None = None,
    ) -> None:
        self.loaded = loaded
        self.plan = plan
        self.units_dir = units_dir
        self.journal = journal
        self.read = read  # told of each configuration a worker read, once the task's units are journaled
        self.submitted: set[str] = set()
        self._pool: ProcessPoolExecutor | None = None
        self._pending: list[tuple[tuple[Step, ...], Future[Task]]] = []
        self._waiting: list[tuple[tuple[Step, ...], Callable[[], bool]]] = []  # not handed out yet

    def submit(self, step: Step, *, ready: Callable[[], bool] | None = None) -> None:
        """Queue a configuration's processing together with its fit (one task: the fit needs its unit),
        handed to a worker once `ready()` is true (at once without it), in submission order."""
        chain = [step]
        if isinstance(step, ProcessStep):
            fit = make_step_id("fit", key=step.configuration)
            if fit in self.plan._index and fit not in self.journal.units:
                chain.append(self.plan.step(fit))
        self.submitted.update(s.id for s in chain)
        self._waiting.append((tuple(chain), ready or (lambda: True)))
        self._hand_out(force=False)

    def _hand_out(self, *, force: bool) -> None:
        """Start the waiting tasks whose units are ready (all of them with `force`), in order."""
        while self._waiting and (force or self._waiting[0][1]()):
            chain, _ = self._waiting.pop(0)
            if self._pool is None:
                start_worker_server()  # usually started with the session already
                workers = min(2, os.cpu_count() or 1)
                self._pool = ProcessPoolExecutor(
                    max_workers=workers,
                    mp_context=worker_context(),
                    initializer=_start_worker,
                    initargs=(self.loaded, self.plan),
                )
            with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
                future = self._pool.submit(_run_task, self.units_dir, tuple(s.id for s in chain))
            self._pending.append((chain, future))

    def collect(self, finished: Callable[[Step, str], None], *, wait: bool) -> None:
        """Journal the background steps that finished (all of them when `wait`: the caller has made sure
        that every unit they read is on disk), telling `finished`."""
        self._hand_out(force=wait)
        still: list[tuple[tuple[Step, ...], Future[Task]]] = []
        for chain, future in self._pending:
            if not (wait or future.done()):
                still.append((chain, future))
                continue
            results, read = future.result()  # a worker's error is raised here, in the main process
            for step, (record, summary) in zip(chain, results, strict=True):
                if record is not None:
                    self.journal.unit_done(record)
                finished(step, summary)
            if read is not None and self.read is not None:
                self.read(read)
        self._pending = still

    @property
    def running(self) -> bool:
        """Whether the workers are started (they have the report's figures and model loaded, `PRELOADED`)."""
        return self._pool is not None

    def call(self, fn: Callable[..., T], /, *args: object) -> Future[T] | None:
        """`fn(*args)` on a worker, if the workers are started and still there (None otherwise: the caller
        runs it itself). For work outside the steps (the report's figures at the end); not journaled."""
        if self._pool is None:
            return None
        with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
            try:
                return self._pool.submit(fn, *args)
            except (BrokenProcessPool, RuntimeError):  # a worker died, or the pool is shut down
                return None

    @property
    def queued(self) -> bool:
        """Whether analyses wait to be handed out (until the units they read are on disk)."""
        return bool(self._waiting)

    @property
    def busy(self) -> bool:
        """Whether analyses are queued or running (not journaled yet)."""
        return bool(self._pending or self._waiting)

    def wait_any(self, *, timeout_s: float | None = None) -> None:
        """Hand out every queued analysis (the caller has made sure their units are on disk) and wait until
        one of those running finishes (or `timeout_s` has passed); `collect` then journals it."""
        self._hand_out(force=True)
        futures_wait([future for _, future in self._pending], timeout=timeout_s, return_when=FIRST_COMPLETED)

    def shutdown(self, finished: Callable[[Step, str], None]) -> None:
        """On any exit: keep the background steps that completed, drop the queued ones (redone on resume)."""
        self._waiting.clear()
        if self._pool is None:
            return
        for _, future in self._pending:
            future.cancel()
        # wait for the running ones here, not inside the pool's shutdown: a second Ctrl-C meanwhile must not
        # interrupt the pool's own bookkeeping (see kill)
        futures_wait([future for _, future in self._pending])
        self._pool.shutdown(wait=True, cancel_futures=True)
        for chain, future in self._pending:
            if future.cancelled() or future.exception() is not None:
                continue
            with contextlib.suppress(Exception):
                for step, (record, summary) in zip(chain, future.result()[0], strict=True):
                    if record is not None:
                        self.journal.unit_done(record)
                    finished(step, summary)
        self._pending.clear()
        self._pool = None

    def kill(self) -> None:
        """Stop at once: end the analysis workers (units are atomic: an unfinished one is redone on resume)."""
        self._waiting.clear()
        if self._pool is None:
            return
        for proc in list(getattr(self._pool, "_processes", {}).values()):
            with contextlib.suppress(Exception):
                proc.kill()
        with contextlib.suppress(Exception):  # quick with the workers gone; its thread must end before exit
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()
        self._pool = None
