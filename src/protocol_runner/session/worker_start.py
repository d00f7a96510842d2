"""How the analysis workers start and end (issue 20): forked from a fork server that the session starts as
early as it can, which imports what they run once (`PRELOADED`) on the other core while the session reads its
protocol; a worker ignores SIGINT (the session decides when to stop) and dies with the session, even one
killed with -9 (a resume may start at once: no worker may still be writing units). Light on purpose: the
session imports it before anything heavy.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.context
import os
import select
import signal
import threading

from .signals import sigint_blocked

PRELOADED = (
    "protocol_runner.session.worker_server",
    "protocol_runner.session.workers",
    "protocol_runner.steps.registry",
    "protocol_runner.analysis.service",
    "protocol_runner.report.figures",
    "protocol_runner.report.figure_cache",
    "protocol_runner.report.load_configuration",
    "protocol_runner.session.worker_warm",  # last: runs the workers' first calls once (worker_warm.py)
)
"""What the workers run, imported once by the fork server (issue 20: with "spawn" every worker imported all
of it again, about a second of CPU each)."""


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
