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
import multiprocessing
import os
import select
import signal
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from pathlib import Path

from ..archive.units import UnitRecord, write_unit
from ..protocol.loader import LoadedProtocol
from ..protocol.plan import Plan, ProcessStep, Step
from ..protocol.processing import processing_settings
from ..protocol.step_ids import step_id as make_step_id
from ..steps.context import StepContext
from ..steps.failures import run_step
from .assembly import ARCHIVE_NAME
from .early_figures import draw_ahead, key_to_draw_ahead
from .journal import Journal
from .signals import sigint_blocked

BACKGROUND_KINDS = frozenset({"process", "fit"})

PRELOADED = (
    "protocol_runner.session.worker_server",
    "protocol_runner.session.workers",
    "protocol_runner.steps.registry",
    "protocol_runner.analysis.service",
    "protocol_runner.report.figures",
    "protocol_runner.report.figure_cache",
    "protocol_runner.report.load_configuration",
)
"""What the workers run, imported once by the fork server (issue 20: with "spawn" every worker imported all
of it again, about a second of CPU each)."""

Results = list[tuple[UnitRecord | None, str]]


def worker_context() -> multiprocessing.context.BaseContext:
    """How workers are started: forked from a fork server (a clean single-threaded process started from the
    session, which imports `PRELOADED` once; never a fork of the session itself, whose unit writer and
    compression threads may hold a lock) where the platform has one, else spawned."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOADED))
    return context


def start_worker_server() -> None:
    """Start the fork server (if it is not running), so that it imports `PRELOADED` on the other core while
    the session starts (its first worker is needed after the first set's trials).

    The server is started with SIGINT ignored, which it keeps (an ignored signal stays ignored across exec,
    and Python then installs no KeyboardInterrupt handler): a Ctrl-C on the terminal, sent to the whole
    process group, neither kills it while it imports nor the workers it forks (they start with SIGINT
    ignored). A SIGINT arriving in the few milliseconds of the start is lost (the session's own stop flag
    is not installed yet when a run starts)."""
    if worker_context().get_start_method() != "forkserver":
        return
    from multiprocessing import forkserver

    if threading.current_thread() is not threading.main_thread():  # signal handlers are the main thread's
        forkserver.ensure_running()
        return
    with sigint_blocked():
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)


def worker_init() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process decides when to stop
    # two workers share the cores with the session: one BLAS thread each, for the worker's whole life
    # (the fits also hold it at one while they run, wherever they are called from)
    import numpy  # noqa: F401  (threadpoolctl limits the BLAS libraries already loaded)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
    # Linux: die with the session process, so a killed session leaves no worker behind writing units
    with contextlib.suppress(Exception):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
        if os.getppid() == 1:  # the parent died before prctl took effect
            os._exit(1)
    _die_with_the_session()


def _die_with_the_session() -> None:
    """A worker forked by the fork server has the server as its parent, so PR_SET_PDEATHSIG fires only once
    the server has ended (after the session, and after its own clean-up): a thread waits on the session
    process itself (a pidfd) and ends the worker at once when the session ends, even killed with -9."""
    session = multiprocessing.parent_process()
    pidfd_open = getattr(os, "pidfd_open", None)
    if session is None or session.pid is None or session.pid == os.getppid() or pidfd_open is None:
        return  # started by the session itself (spawn): PR_SET_PDEATHSIG is enough
    try:
        fd = pidfd_open(session.pid)
    except OSError:  # the session is already gone
        os._exit(1)

    def watch() -> None:
        select.select([fd], [], [])  # readable once the session process has ended
        os._exit(1)

    threading.Thread(target=watch, name="session-watch", daemon=True).start()


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
        outcome = run_step(step, ctx)
        record = write_unit(units_dir, step.id, outcome.fill) if outcome.fill is not None else None
        done.append((record, outcome.summary))
    key = key_to_draw_ahead(plan, step_ids)
    if key is not None:  # the configuration's analyses are written: its report figures now, not at the end
        draw_ahead(plan, units_dir, key, units_dir.parent / ARCHIVE_NAME)
    return done


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
                    initializer=worker_init,
                )
            with sigint_blocked():  # a worker started here must not die of the terminal's Ctrl-C
                future = self._pool.submit(
                    run_analysis_steps, self.loaded, self.plan, self.units_dir, tuple(s.id for s in chain)
                )
            self._pending.append((chain, future))

    def collect(self, finished: Callable[[Step, str], None], *, wait: bool) -> None:
        """Journal the background steps that finished (all of them when `wait`: the caller has made sure
        that every unit they read is on disk), telling `finished`."""
        self._hand_out(force=wait)
        still: list[tuple[tuple[Step, ...], Future[Results]]] = []
        for chain, future in self._pending:
            if not (wait or future.done()):
                still.append((chain, future))
                continue
            results = future.result()  # a worker's error is raised here, in the main process
            for step, (record, summary) in zip(chain, results, strict=True):
                if record is not None:
                    self.journal.unit_done(record)
                finished(step, summary)
        self._pending = still

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
                for step, (record, summary) in zip(chain, future.result(), strict=True):
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
