"""Write errors that h5py can only print: collected for the file being written, so that its writer fails.

When the last reference to an h5py object goes, h5py closes its HDF5 identifier in the deallocator, and
HDF5 may then write cached data to the file. If that write fails (a full disk), h5py cannot raise: Python
only prints it (`sys.unraisablehook`, and h5py through `sys.excepthook`), and the file could later be
taken as complete with the failed write's bytes missing.

`checked_h5_write(path)` collects those errors for the file at `path` (HDF5 names the file in the
message) and raises the first once the block that writes and closes the file has ended. When the block
raises instead, its own error is the one that counts. Errors about other files, and every other
unraisable exception, go to the hook that was in place.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import traceback
from collections.abc import Iterator
from pathlib import Path
from typing import Any

_lock = threading.Lock()
_watched: dict[str, list[BaseException]] = {}  # file name as HDF5 reports it -> errors met writing it
_forward: list[Any] = []  # while files are watched: the hook that was in place when the first one began
_forward_print: list[Any] = []  # and the `sys.excepthook` then in place


def _collected(value: BaseException | None) -> bool:
    """Whether `value` is a write error of a watched file (then kept in its list, once)."""
    if value is None:
        return False
    text = str(value)
    with _lock:
        for name, errors in _watched.items():
            if name in text:
                if not any(e is value for e in errors):
                    errors.append(value)
                return True
    return False


def _hook(unraisable: Any) -> None:  # sys.UnraisableHookArgs
    if _collected(unraisable.exc_value):
        return
    with _lock:
        forward = _forward[0] if _forward else sys.__unraisablehook__
    try:
        forward(unraisable)
    except Exception:  # a hook its owner has since taken down: Python's own prints it
        sys.__unraisablehook__(unraisable)


def _print_hook(kind: Any, value: BaseException, tb: Any) -> None:
    """`sys.excepthook` while files are watched: h5py's deallocator prints a watched file's write error
    through it (then hands it to `_hook`); anything else is printed as before."""
    if _collected(value):
        return
    with _lock:
        forward = _forward_print[0] if _forward_print else sys.__excepthook__
    forward(kind, value, tb)


@contextlib.contextmanager
def checked_h5_write(path: Path) -> Iterator[None]:
    """Around the writing (opening to closing) of the HDF5 file at `path`, opened by that name: a write
    h5py could only print fails the block, raised as an `OSError` (its `errno` ENOSPC for a full disk,
    which `diskfull.is_disk_full` recognises). The hooks are in place only while some file is being
    written (the first writer puts them in, the last one takes them out if nothing replaced them)."""
    key = str(path)
    errors: list[BaseException] = []
    with _lock:
        if not _watched and sys.unraisablehook is not _hook:
            _forward[:] = [sys.unraisablehook]
            sys.unraisablehook = _hook
        if not _watched and sys.excepthook is not _print_hook:
            _forward_print[:] = [sys.excepthook]
            sys.excepthook = _print_hook
        _watched[key] = errors
    try:
        try:
            yield
        except BaseException as exc:
            traceback.clear_frames(exc.__traceback__)  # free the h5py objects they hold, errors collected
            raise
    finally:
        with _lock:
            if _watched.get(key) is errors:
                del _watched[key]
            if not _watched and sys.unraisablehook is _hook and _forward:
                sys.unraisablehook = _forward[0]
                _forward.clear()
            if not _watched and sys.excepthook is _print_hook and _forward_print:
                sys.excepthook = _forward_print[0]
                _forward_print.clear()
    if errors:
        text = str(errors[0])
        full = "errno = 28" in text or "No space left on device" in text
        raise OSError(28 if full else 5, f"writing {path} failed: {text}", str(path))
