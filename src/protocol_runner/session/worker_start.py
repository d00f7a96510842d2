"""How the analysis workers start and end (issue 20): forked from a fork server that the session starts as
early as it can, which imports what they run once (`PRELOADED`) on the other core while the session reads its
protocol; a worker ignores SIGINT (the session decides when to stop) and dies with the session, even one
killed with -9 (a resume may start at once: no worker may still be writing units). Light on purpose: the
session imports it before anything heavy.

Forked from the session (Linux, CPython 3.11/3.12). multiprocessing starts its fork server as a fresh
interpreter, which imports everything again, also what the session imports itself (numpy, h5py, numba,
pydantic and the protocol schema: ~0.4 s of CPU done twice). A command-line
session (`commands.run`/`resume`) therefore imports `SHARED` first and then forks itself: the child runs
`multiprocessing.forkserver.main` on a listener and an "alive" pipe exactly as the fresh server would, and
imports only the rest of `PRELOADED`. The fork is safe because, at that moment:

- the session runs no thread but its main thread (`threading.active_count() == 1`, checked; else the normal
  start). The only other threads are OpenBLAS's native pool threads, which OpenBLAS stops and restarts
  around a fork itself (pthread_atfork), as it does when the server forks its workers (Python 3.12, which
  counts native threads, would warn of them: that warning is silenced for this fork);
- it holds no session file, journal lock or HDF5 file (nothing is opened before the protocol is read), and
  has started no process (so the child inherits no multiprocessing children, pools or queues);
- stdout and stderr have been flushed, so the child inherits empty buffers; it never flushes them and
  always leaves by `os._exit`: the session's atexit handlers and multiprocessing finalizers (its temporary
  folder) never run in it;
- SIGINT is blocked and ignored around the fork as around the normal start, so the child keeps it ignored
  (forkserver.main ignores it too), and the child closes its copy of the alive pipe's write end, so it still
  ends when the session and its workers have ended. A worker's parent process (for the death watch) is the
  session either way (`multiprocessing.parent_process()` comes from the pickled process object);
- the child inherits the session's memory as it is then: its modules (and `__main__`, the command line,
  which a worker then finds in place instead of importing it again), `sys.path` and the scipy docstring
  patch; the `ForkServer`'s lock is free (one thread) and its fields still empty; the resource tracker is
  started after the fork, so the server holds no copy of its pipe. Only the command line's own process
  forks (`commands._command_line`): a program calling `run` in its own process (a test) may have replaced
  functions the workers run, which a forked server would keep for every later worker.

Private CPython 3.11/3.12 state this relies on (any other version, platform or failure: the normal start):
`multiprocessing.forkserver._forkserver`, the module's singleton `ForkServer`, whose `_forkserver_address`
(the listener's socket path), `_forkserver_alive_fd` (the write end of the alive pipe, sent to every
worker) and `_forkserver_pid` are set in the parent exactly as `ForkServer.ensure_running` sets them, so
that `connect_to_new_process` (and `ensure_running`'s liveness check, a `waitpid` on the server, which is
the session's child either way) use the forked server; `ForkServer._preload_modules`; and the signature
`forkserver.main(listener_fd, alive_r, preload)` and `multiprocessing.connection.arbitrary_address`.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.context
import os
import select
import signal
import socket
import sys
import threading
import warnings
from typing import Any, NoReturn

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


SHARED = (
    "numpy",
    "h5py",
    "numba",
    "pydantic",
    "protocol_runner.protocol.loader",
    "protocol_runner.session.workers",
)
"""What both the session and the fork server import (the session soon after it starts, or at its first
calibration check and simulated trial), imported before the session forks the server: once for both. Not
scipy: the server imports it on the other core while the session starts; the session imports the parts it
uses (signal and optimize for its calibration checks and brace-off smoothing, stats for the report's
intervals) when it first needs them."""


def worker_context() -> multiprocessing.context.BaseContext:
    """How workers are started: forked from a fork server (a clean single-threaded process started from the
    session, which imports `PRELOADED` once; never a fork of the session itself, whose unit writer and
    compression threads may hold a lock) where the platform has one, else spawned."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOADED))
    return context


def start_worker_server(*, fork_session: bool = False) -> None:
    """Start the fork server (if it is not running), so that it imports `PRELOADED` on the other core while
    the session starts (its first worker is needed after the first set's trials).

    The server is started with SIGINT ignored, which it keeps (an ignored signal stays ignored across exec,
    and Python then installs no KeyboardInterrupt handler): a Ctrl-C on the terminal, sent to the whole
    process group, neither kills it while it imports nor the workers it forks (they start with SIGINT
    ignored). A SIGINT arriving in the few milliseconds of the start is lost (the session's own stop flag
    is not installed yet when a run starts).

    With `fork_session` (a command-line session, first thing, holding no file yet), the server is a fork of
    this process after it has imported `SHARED` (module docstring), where that is possible."""
    if worker_context().get_start_method() != "forkserver":
        return
    from multiprocessing import forkserver

    if threading.current_thread() is not threading.main_thread():  # signal handlers are the main thread's
        forkserver.ensure_running()
        return
    forking = (
        fork_session and _can_fork(forkserver) and _import_shared()
    )  # imports: outside the SIGINT window
    with sigint_blocked():
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            if not (forking and _fork_server(forkserver)):
                forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)


def _can_fork(forkserver: object) -> bool:
    server = getattr(forkserver, "_forkserver", None)
    return (
        sys.platform == "linux"
        and (3, 11) <= sys.version_info[:2] < (3, 13)
        and hasattr(os, "fork")
        and server is not None
        and getattr(server, "_forkserver_pid", 0) is None
        and threading.active_count() == 1
    )


def _import_shared() -> bool:
    import importlib

    try:
        for name in SHARED:
            importlib.import_module(name)
    except Exception:
        return False
    _load_numba_target()
    return threading.active_count() == 1  # none of them started a thread


def _load_numba_target() -> None:
    """Load numba's CPU target (its implementation registries, about 0.09 s of CPU), which numba otherwise
    loads at a process's first compiled call: the session at its simulator's first step, the fork server
    at its warm-up (`worker_warm`). Loaded before the fork, once for both. Best effort: numba's
    `cpu_target` is internal (numba 0.59-0.61), and without it each loads its own as before."""
    with contextlib.suppress(Exception):
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()


def _fork_server(forkserver: Any) -> bool:
    """Fork this process into the fork server (module docstring); False, with nothing left behind, where it
    cannot be done."""
    from multiprocessing import connection, resource_tracker, util

    server = forkserver._forkserver
    preload = list(server._preload_modules or PRELOADED)
    try:
        listener = socket.socket(socket.AF_UNIX)
    except OSError:
        return False
    alive_r = alive_w = -1
    try:
        address = connection.arbitrary_address("AF_UNIX")  # type: ignore[attr-defined]
        listener.bind(address)
        if not util.is_abstract_socket_namespace(address):
            os.chmod(address, 0o600)
        listener.listen()
        alive_r, alive_w = os.pipe()
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
        with warnings.catch_warnings():  # 3.12 warns of OpenBLAS's threads (module docstring)
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
    except Exception:
        listener.close()
        for fd in (alive_r, alive_w):
            if fd >= 0:
                os.close(fd)
        return False
    if pid == 0:
        _serve(forkserver, listener.fileno(), alive_r, alive_w, preload)  # never returns
    os.close(alive_r)
    listener.close()
    server._forkserver_address = address
    server._forkserver_alive_fd = alive_w
    server._forkserver_pid = pid
    with contextlib.suppress(Exception):  # after the fork: the server holds no copy of the tracker's pipe
        resource_tracker.ensure_running()
    return True


def _serve(forkserver: Any, listener_fd: int, alive_r: int, alive_w: int, preload: list[str]) -> NoReturn:
    """The forked server: multiprocessing's own loop (which ends, raising SystemExit, once every holder of
    the alive pipe's write end has ended), left by os._exit whatever happens."""
    code = 1
    try:
        os.close(alive_w)  # the session and the workers hold it; the server must not
        forkserver.main(listener_fd, alive_r, preload)
        code = 0
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else 0
    except BaseException:
        with contextlib.suppress(BaseException):
            import traceback

            traceback.print_exc()
            sys.stderr.flush()
    finally:
        os._exit(code)


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
