"""The analysis worker pool: processing and fit steps run in a worker process beside the trials.

A worker writes the step's unit (write, fsync, rename); the main process journals it once the task has
ended, so a step is journaled only once its unit is on disk. A stop waits for the analyses in progress and
redoes the rest on resume.

Workers are forked from a fork server where the platform has one, else spawned (`worker_context`); every
argument is pickled, so that both work alike. A worker ignores SIGINT (the session decides when to stop),
runs BLAS on one thread and ends as soon as the session process ends, even one killed with -9: a resume
may start at once, and no worker may still be writing units then.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.context
import os
import signal
import threading
import warnings
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from pathlib import Path

from ..archive.units import UnitRecord, write_unit
from ..protocol.loaded import LoadedProtocol
from ..protocol.plan_steps import Plan, ProcessStep, Step
from ..protocol.processing import processing_settings
from ..protocol.step_ids import step_id as make_step_id
from ..steps.context import StepContext
from ..steps.failures import run_step
from .journal import Journal
from .signals import sigint_blocked

PRELOADED = ("protocol_runner.steps.registry", "protocol_runner.analysis.service")
"""What the workers run, imported once by the fork server instead of by every worker it forks."""

Warned = tuple[tuple[str, int], ...]  # (warning kind, how often), in the order first raised
Results = list[tuple[UnitRecord | None, str, Warned]]
"""A task's units, summaries and the warnings each step raised (`warning_kinds`), in step order."""


def worker_context() -> multiprocessing.context.BaseContext:
    """How workers are started: forked from a fork server (a clean process started for them, which imports
    `PRELOADED` once) where the platform has one (and `os.fork`: not on Windows), else spawned."""
    if not hasattr(os, "fork") or "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOADED))
    return context


def analysis_pool(initializer: Callable[..., None] | None = None, *initargs: object) -> ProcessPoolExecutor:
    """Worker processes started as `worker_context` says, each running `initializer` (default `worker_init`:
    SIGINT left to the main process, BLAS on one thread); `--report --reprocess` uses the default."""
    start: Callable[..., None] = initializer or worker_init
    with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
        return ProcessPoolExecutor(
            max_workers=min(2, os.cpu_count() or 1),
            mp_context=worker_context(),
            initializer=start,
            initargs=initargs,
        )


def worker_init() -> None:
    """A worker's start: SIGINT ignored, BLAS on one thread, and a watch that ends the worker with the
    session."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process decides when to stop
    # two workers share the cores with the session: one BLAS thread each, for the worker's whole life
    import numpy  # noqa: F401  (threadpoolctl limits the BLAS libraries already loaded)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
    session = multiprocessing.parent_process()
    if session is not None:
        # `join` returns once the session process has ended (its end of a pipe to this worker is closed),
        # whatever its start method and however it ended
        threading.Thread(target=_exit_when_ended, args=(session,), name="session-watch", daemon=True).start()


def _exit_when_ended(session: multiprocessing.process.BaseProcess) -> None:
    session.join()
    os._exit(1)


# in a worker: the pool's protocol and plan (`_start_worker`)
_SESSION: list[tuple[LoadedProtocol, Plan]] = []


def _start_worker(loaded: LoadedProtocol, plan: Plan) -> None:
    """A worker's start (`worker_init`), keeping the session's protocol and plan for every task it runs (sent
    once per worker instead of with each task)."""
    worker_init()
    _SESSION[:] = [(loaded, plan)]


def _run_task(units_dir: Path, step_ids: tuple[str, ...]) -> Results:
    """`run_analysis_steps` with the protocol and plan the worker started with."""
    loaded, plan = _SESSION[0]
    return run_analysis_steps(loaded, plan, units_dir, step_ids)


def run_analysis_steps(
    loaded: LoadedProtocol, plan: Plan, units_dir: Path, step_ids: tuple[str, ...]
) -> Results:
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
    done: Results = []
    for step_id in step_ids:
        step = plan.step(step_id)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            outcome = run_step(step, ctx)
        record = write_unit(units_dir, step.id, outcome.fill) if outcome.fill is not None else None
        done.append((record, outcome.summary, warning_kinds(caught)))
    return done


def warning_kinds(caught: list[warnings.WarningMessage]) -> Warned:
    """The kinds of the warnings a step raised (category, message, where), each once with how often, in
    the order first raised (a worker's stderr reaches no one)."""
    counts: dict[str, int] = {}
    for w in caught:
        where = Path(w.filename)
        shown = "/".join(where.parts[-3:]) if len(where.parts) > 3 else str(where)
        kind = f"{w.category.__name__}: {w.message} ({shown}:{w.lineno})"
        counts[kind] = counts.get(kind, 0) + 1
    return tuple(counts.items())


class AnalysisPool:
    """Background analysis steps: submitted in plan order, journaled in the main process when done."""

    def __init__(self, loaded: LoadedProtocol, plan: Plan, units_dir: Path, journal: Journal) -> None:
        self.loaded = loaded
        self.plan = plan
        self.units_dir = units_dir
        self.journal = journal
        self.submitted: set[str] = set()
        self._pool: ProcessPoolExecutor | None = None
        self._pending: list[tuple[tuple[Step, ...], Future[Results]]] = []
        self._warned: set[str] = set()  # the warning kinds already shown in full

    def submit(self, step: Step) -> None:
        """Hand a configuration's processing to a worker together with its fit (one task: the fit needs its
        unit). The units it reads must be on disk."""
        chain = [step]
        if isinstance(step, ProcessStep):
            fit = make_step_id("fit", key=step.configuration)
            if fit in self.plan and fit not in self.journal.units:
                chain.append(self.plan.step(fit))
        self.submitted.update(s.id for s in chain)
        if self._pool is None:
            self._pool = analysis_pool(_start_worker, self.loaded, self.plan)
        # blocked again: creating the pool may start multiprocessing's resource tracker, which unblocks
        # SIGINT in this thread once it has started it; the workers (and the fork server) start here
        with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
            future = self._pool.submit(_run_task, self.units_dir, tuple(s.id for s in chain))
        self._pending.append((tuple(chain), future))

    def collect(self, finished: Callable[[Step, str], None], *, wait: bool = False) -> None:
        """Journal the background steps that finished (with `wait`, all of them, waiting for those still
        running), telling `finished`, in submission order."""
        if wait:
            futures_wait([future for _, future in self._pending])
        still: list[tuple[tuple[Step, ...], Future[Results]]] = []
        for chain, future in self._pending:
            if still or not future.done():  # journaled in submission order
                still.append((chain, future))
                continue
            self._journal(chain, future.result(), finished)  # a worker's error is raised here
        self._pending = still

    def _journal(
        self, chain: tuple[Step, ...], results: Results, finished: Callable[[Step, str], None]
    ) -> None:
        for step, (record, summary, raised) in zip(chain, results, strict=True):
            if record is not None:
                self.journal.unit_done(record)
            finished(step, summary + self._warnings_text(raised))

    def _warnings_text(self, raised: Warned) -> str:
        """What a step's line adds for the warnings it raised: each kind in full the first time the session
        meets it, after that its category only."""
        parts: list[str] = []
        for kind, count in raised:
            times = f" ({count} times)" if count > 1 else ""
            if kind in self._warned:
                parts.append(f"{kind.split(':', 1)[0]} again{times}")
            else:
                self._warned.add(kind)
                parts.append(f"{kind}{times}")
        return "".join(f"; WARNING {part}" for part in parts)

    @property
    def running(self) -> bool:
        """Whether the workers are started."""
        return self._pool is not None

    def shutdown(self, finished: Callable[[Step, str], None]) -> None:
        """On any exit: keep the background steps that complete, drop those not started (redone on resume)."""
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
                self._journal(chain, future.result(), finished)
        self._pending.clear()
        self._pool = None

    def kill(self) -> None:
        """Stop at once: end the analysis workers (units are atomic: an unfinished one is redone on resume)."""
        if self._pool is None:
            return
        for process in multiprocessing.active_children():  # this session's only processes: the workers
            with contextlib.suppress(Exception):
                process.kill()
        # not waited for: an interrupt may have left the pool's own thread waiting on a lock or a queue it
        # never gets (seen: a futex wait of minutes); `run-protocol` then ends without waiting for it
        # (cli.entry, signals.stopped_at_once)
        with contextlib.suppress(Exception):
            self._pool.shutdown(wait=False, cancel_futures=True)
        self._pending.clear()
        self._pool = None
