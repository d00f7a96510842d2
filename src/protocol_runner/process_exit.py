"""End the `run-protocol` process without the interpreter's teardown, when nothing would be lost by it.

After `cli.main` returns, a normal exit still spends ~0.3 s of wall time on a knee dry run finalizing the
interpreter (measured from main's return to the parent's `wait4`: 0.32 s, 0.03 s with this exit): joining
threads, the atexit handlers, a full garbage collection (~0.1 s with numpy, numba, matplotlib and h5py
loaded), then tearing down every module. None of it writes anything of ours once the
session has closed its files, so `exit_now_if_safe` runs the atexit handlers (all of them, in their usual
order) and ends the process with `os._exit`, but only when all of these hold; otherwise it returns and the
caller exits normally:

- no thread other than the main one is alive and non-daemon (a normal exit would wait for it). Daemon
  threads (the archive's `h5-deflate_*` workers, the report warm-up, the monitor) are frozen by a normal exit
  too, so stopping them here loses nothing more. With no such thread alive, the callbacks a normal exit runs
  first (`threading._register_atexit`: concurrent.futures' two `_python_exit`) only join dead threads;
- no child process of `multiprocessing` is alive (`active_children()`): a normal exit would join it. The
  fork server and the resource tracker are not children; they end when their pipe closes, which the kernel
  does for `os._exit` as for a normal exit;
- after the atexit handlers: no HDF5 file is open in this process (asked of h5py only if it was imported);
  an open one would lose HDF5's flush and close;
- no regular file other than stdin, stdout and stderr is open for writing (descriptors listed in
  /proc/self/fd or /dev/fd, access mode from fcntl; where that cannot be known, exit normally): a Python
  file object still open there could hold buffered bytes that its close at teardown would write (or be a
  `NamedTemporaryFile` that its close would remove);
- stdout and stderr flushed without an error (a closed pipe: the normal exit reports it as before).

The atexit handlers a knee dry run registers (checked by wrapping `atexit.register` during one), all run
here by `atexit._run_exitfuncs()` (which then forgets them, so a fallback to the normal exit does not repeat
them): multiprocessing's `_exit_function` (its finalizers; it would terminate and join children, none by
the check above), `logging.shutdown` (flushes and closes the handlers), h5py's `unregister_converters`,
llvmlite's and numba's `_at_shutdown` (numba's runtime and dispatcher finalizers via `weakref.finalize`),
PIL's `clear_cache`, matplotlib's `Gcf.destroy_all`; `weakref.finalize` objects (a `TemporaryDirectory`'s
removal) run there too. Running them costs well under a millisecond. When a check after them sends the
process to the normal exit, that exit has no handler left to run and no thread to join (checked before).

Only the command-line entry (`cli.entry`) calls this: code that calls `cli.main(argv)` in its own process
(the tests do) gets the exit code back and goes on.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import stat
import sys
import threading


def exit_now_if_safe(code: int) -> None:
    """Run the atexit handlers and `os._exit(code)` if nothing is left that the interpreter's teardown would
    finish (module docstring); otherwise return, the caller then exits normally (`sys.exit(code)`)."""
    if _threads_or_children_alive():
        return
    atexit._run_exitfuncs()
    if not _streams_flushed() or _hdf5_files_open() or _files_open_for_writing():
        return
    os._exit(code)


def _threads_or_children_alive() -> bool:
    main = threading.main_thread()
    if any(t is not main and not t.daemon and t.is_alive() for t in threading.enumerate()):
        return True
    if "multiprocessing" in sys.modules:
        import multiprocessing

        return bool(multiprocessing.active_children())
    return False


def _streams_flushed() -> bool:
    try:
        for stream in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):  # a closed pipe or a closed stream
        return False
    return True


def _hdf5_files_open() -> bool:
    h5py = sys.modules.get("h5py")  # not imported: no file can be open through it
    if h5py is None:
        return False
    return bool(h5py.h5f.get_obj_count(h5py.h5f.OBJ_ALL, h5py.h5f.OBJ_FILE))


def _files_open_for_writing() -> bool:
    """True if a regular file other than stdin/stdout/stderr is open for writing, or if that cannot be known."""
    if sys.platform == "win32":  # no fcntl: unknown, so not safe
        return True
    import fcntl

    try:
        descriptors = [
            int(fd) for fd in os.listdir("/proc/self/fd" if os.path.isdir("/proc/self/fd") else "/dev/fd")
        ]
    except OSError:  # no descriptor listing: unknown, so not safe
        return True
    for fd in descriptors:
        if fd <= 2:
            continue
        try:
            writable = (fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE) != os.O_RDONLY
            if writable and stat.S_ISREG(os.fstat(fd).st_mode):
                return True
        except OSError:  # closed since the listing (the listing's own descriptor)
            continue
    return False


def exit_after_a_full_disk(code: int) -> None:
    """End the process at once after a session stopped on a full disk: HDF5 may hold a file whose close
    failed for lack of space, and the interpreter's teardown closing it again crashed the process
    (a segmentation fault instead of exit 130). Nothing of the session is lost by skipping the teardown:
    every finished unit is on disk, fsynced and journaled, and whatever was still being written is a
    temporary file that a resume removes or redoes, as after a kill (docs/session.md). The streams and the
    log are flushed first."""
    import logging

    _streams_flushed()
    with contextlib.suppress(Exception):
        logging.shutdown()
    os._exit(code)
