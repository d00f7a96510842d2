"""archive/h5_write_errors.py: a write that h5py can only print (from an object's deallocator, a full disk)
fails the unit or the archive being written instead of being printed and forgotten."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from protocol_runner.archive.diskfull import DiskFull
from protocol_runner.archive.h5_write_errors import checked_h5_write
from protocol_runner.archive.units import write_unit


class _FreedWithAFailedWrite:
    """What h5py does when freeing an object whose data HDF5 then fails to write: it cannot raise from the
    deallocator, so Python hands the error to `sys.unraisablehook` (the message is HDF5's, naming the file)."""

    def __init__(
        self, filename: Path, errno_text: str = "errno = 28, error message = 'No space left on device'"
    ):
        self.message = (
            "Can't decrement id ref count (file write failed: time = Wed Nov 25 04:18:26 2026\n, "
            f"filename = '{filename}', file descriptor = 6, {errno_text}, total write size = 11774)"
        )

    def __del__(self) -> None:
        raise RuntimeError(self.message)


def test_a_unit_whose_write_h5py_could_only_print_is_not_kept(tmp_path: Path, capsys: Any) -> None:
    units = tmp_path / "units"

    def fill(f: h5py.File) -> None:
        f.create_dataset("x", data=np.arange(10.0))
        obj = _FreedWithAFailedWrite(units / "process__k01.h5.partial")
        del obj  # the write fails here, where the program cannot see it

    with pytest.raises(DiskFull, match="disk full while saving process:k01"):
        write_unit(units, "process:k01", fill)
    assert list(units.iterdir()) == []  # neither the unit nor its partial file
    assert "Exception ignored" not in capsys.readouterr().err


class _FreedPrintingItsTraceback(_FreedWithAFailedWrite):
    """h5py's deallocator as it is compiled (Cython, full tracebacks): it prints the error's traceback through
    `sys.excepthook` first, then hands the error to `sys.unraisablehook`."""

    def __del__(self) -> None:
        try:
            raise RuntimeError(self.message)
        except RuntimeError:
            sys.excepthook(*sys.exc_info())
            raise


def test_a_failed_write_h5py_prints_itself_is_not_printed_and_fails_the_unit(
    tmp_path: Path, capsys: Any
) -> None:
    units = tmp_path / "units"

    def fill(f: h5py.File) -> None:
        f.create_dataset("x", data=np.arange(10.0))
        obj = _FreedPrintingItsTraceback(units / "process__k12.h5.partial")
        del obj

    with pytest.raises(DiskFull, match="disk full while saving process:k12"):
        write_unit(units, "process:k12", fill)
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err
    assert sys.excepthook is sys.__excepthook__  # put back once no file is written


def test_other_prints_while_a_file_is_written_go_to_the_excepthook_in_place(tmp_path: Path) -> None:
    seen: list[str] = []

    def hook(kind: Any, value: BaseException | None, tb: Any) -> None:
        seen.append(str(value))

    previous = sys.excepthook
    sys.excepthook = hook
    try:
        with checked_h5_write(tmp_path / "a.h5.partial"):
            try:
                raise ValueError("about b.h5.partial, not the file being written")
            except ValueError:
                sys.excepthook(*sys.exc_info())
        assert seen == ["about b.h5.partial, not the file being written"]
        assert sys.excepthook is hook  # in place again once no file is written
    finally:
        sys.excepthook = previous


def test_other_files_errors_and_other_unraisable_exceptions_go_to_the_hook_in_place(tmp_path: Path) -> None:
    seen: list[str] = []
    previous = sys.unraisablehook
    sys.unraisablehook = lambda u: seen.append(str(u.exc_value))
    try:
        with checked_h5_write(tmp_path / "a.h5.partial"):
            obj = _FreedWithAFailedWrite(tmp_path / "b.h5.partial")
            del obj
        assert len(seen) == 1 and "b.h5.partial" in seen[0]
        with (
            pytest.raises(OSError, match=r"writing .*a\.h5\.partial failed") as raised,
            checked_h5_write(tmp_path / "a.h5.partial"),
        ):
            obj = _FreedWithAFailedWrite(tmp_path / "a.h5.partial", "errno = 5, error message = 'I/O'")
            del obj
        assert raised.value.errno == 5 and len(seen) == 1
    finally:
        sys.unraisablehook = previous


def test_a_unit_written_without_such_errors_is_kept(tmp_path: Path) -> None:
    record = write_unit(
        tmp_path / "units", "process:k01", lambda f: f.create_dataset("x", data=np.arange(3.0))
    )
    with h5py.File(tmp_path / "units" / record.file) as f:
        assert list(f["x"][:]) == [0.0, 1.0, 2.0]


class _OtherError:
    def __del__(self) -> None:
        raise ValueError("not about any file being written")


def test_the_hook_is_in_place_only_while_a_file_is_written_and_then_restored(tmp_path: Path) -> None:
    """Like the session's stop flag: a hook in place before a unit is written gets every other unraisable
    exception meanwhile and is the hook again after."""
    seen: list[str] = []

    def stop_flag_hook(unraisable: Any) -> None:
        seen.append(str(unraisable.exc_value))

    previous = sys.unraisablehook
    sys.unraisablehook = stop_flag_hook
    try:

        def fill(f: h5py.File) -> None:
            assert sys.unraisablehook is not stop_flag_hook  # the collecting hook, while writing
            obj = _OtherError()
            del obj

        write_unit(tmp_path / "units", "process:k01", fill)
        assert sys.unraisablehook is stop_flag_hook
        assert seen == ["not about any file being written"]
    finally:
        sys.unraisablehook = previous


def test_a_hook_taken_down_by_its_owner_meanwhile_does_not_break_the_collecting_one(
    tmp_path: Path, capsys: Any
) -> None:
    """The session's stop flag, uninstalled, leaves a hook that can no longer be called: an unrelated
    unraisable exception is then printed as Python prints it, not lost in a second error."""

    class TakenDown:
        previous: Any = None

        def __call__(self, unraisable: Any) -> None:
            self.previous(unraisable)  # None once its owner has uninstalled it: a TypeError

    previous = sys.unraisablehook
    sys.unraisablehook = TakenDown()
    try:
        with checked_h5_write(tmp_path / "a.h5.partial"):
            obj = _OtherError()
            del obj
    finally:
        sys.unraisablehook = previous
    err = capsys.readouterr().err
    assert "not about any file being written" in err and "TypeError" not in err
